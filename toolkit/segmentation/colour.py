"""Per-part colour models: Gaussian mixtures learned from one frame's confident pixels (source 000 §2.3).

Colour spaces (pixel features, all scaled to comparable ranges):

``"rgb"``
    R, G, B in [0, 1].
``"lab"``
    CIE L*a*b* (OpenCV, 8-bit input) divided by 100 (L) and 128 (a, b).
``"hsv"``
    A hue angle on the unit circle weighted by saturation (``s cos h``,
    ``s sin h``) and the value: no wrap-around at red.
``"chroma"``
    Intensity-normalised chromaticity (r, g) = (R, G) / (R + G + B) plus the
    intensity, for shading-insensitive models.
"""

from __future__ import annotations

from dataclasses import dataclass

import warnings

import cv2
import numpy as np
from sklearn.exceptions import ConvergenceWarning
from sklearn.mixture import GaussianMixture
from threadpoolctl import ThreadpoolController

from toolkit.errors import InputError

COLOUR_SPACES = ("rgb", "lab", "hsv", "chroma")
#: BLAS / OpenMP threads while fitting and scoring: the problems are tiny (a few
#: thousand 3-vectors) and thread start-up dominated (measured: 2.6 s per frame
#: with the default pools against 0.2 s with one thread on 2 cores).
_THREADS = 1
_POOLS = None


def _one_thread():
    """Context manager limiting BLAS / OpenMP to :data:`_THREADS` threads.

    The controller is built once: ``threadpool_limits`` scans the loaded
    libraries on every call (about 25 ms each, more than a small mixture fit).
    """
    global _POOLS
    if _POOLS is None:
        _POOLS = ThreadpoolController()
    return _POOLS.limit(limits=_THREADS)


def colour_features(image: np.ndarray, space: str) -> np.ndarray:
    """Per-pixel colour features.

    Parameters
    ----------
    image : ndarray of shape (H, W, 3) uint8 RGB, or (N, 3) uint8 RGB
    space : str
        One of :data:`COLOUR_SPACES`.

    Returns
    -------
    ndarray of shape (H, W, 3) or (N, 3), float32
    """
    a = np.asarray(image)
    if a.shape[-1] != 3 or a.ndim not in (2, 3):
        raise InputError("colour_features: image", "(H, W, 3) or (N, 3) RGB", f"shape {a.shape}")
    if a.dtype != np.uint8:
        raise InputError("colour_features: image", "uint8 RGB", f"dtype {a.dtype}")
    img = a if a.ndim == 3 else a[None]
    if space == "rgb":
        f = img.astype(np.float32) / 255.0
    elif space == "lab":
        lab = cv2.cvtColor(np.ascontiguousarray(img), cv2.COLOR_RGB2LAB).astype(np.float32)
        f = np.stack([lab[..., 0] / 255.0, (lab[..., 1] - 128.0) / 128.0, (lab[..., 2] - 128.0) / 128.0], -1)
    elif space == "hsv":
        hsv = cv2.cvtColor(np.ascontiguousarray(img), cv2.COLOR_RGB2HSV_FULL).astype(np.float32)
        h = hsv[..., 0] * (2 * np.pi / 256.0)
        s = hsv[..., 1] / 255.0
        f = np.stack([s * np.cos(h), s * np.sin(h), hsv[..., 2] / 255.0], -1)
    elif space == "chroma":
        x = img.astype(np.float32)
        tot = x.sum(-1) + 1.0
        f = np.stack([x[..., 0] / tot, x[..., 1] / tot, tot / (3 * 255.0)], -1)
    else:
        raise InputError("colour_features: space", f"one of {list(COLOUR_SPACES)}", repr(space))
    return (f if a.ndim == 3 else f[0]).astype(np.float32)


@dataclass(frozen=True)
class PartColourModels:
    """One Gaussian mixture per body part.

    Attributes
    ----------
    models : dict of int -> GaussianMixture
        Part id (1..n_parts) -> fitted mixture (parts without a model absent).
    n_parts : int
    counts : ndarray of shape (n_parts,)
        Confident pixels available per part.
    space : str
        Colour space of the features.
    """

    models: dict
    n_parts: int
    counts: np.ndarray
    space: str

    @property
    def parts_without_model(self) -> tuple:
        """Part ids (1-based) that have no model, ascending."""
        return tuple(p for p in range(1, self.n_parts + 1) if p not in self.models)

    def log_likelihood(self, features: np.ndarray) -> np.ndarray:
        """Log density of each part's model, (N, n_parts); ``-inf`` for parts without a model."""
        f = np.asarray(features, np.float64)
        out = np.full((len(f), self.n_parts), -np.inf)
        if len(f):
            with _one_thread():
                for p, g in self.models.items():
                    out[:, p - 1] = g.score_samples(f)
        return out

    def summary(self, part_names) -> str:
        """Text: per part, the mixture weights and means (in feature units)."""
        lines = [f"colour space {self.space}"]
        for p in range(1, self.n_parts + 1):
            name = part_names[p - 1]
            if p not in self.models:
                lines.append(f"{name}: no model ({int(self.counts[p - 1])} confident px)")
                continue
            g = self.models[p]
            comps = "; ".join(f"w={w:.2f} mean=({', '.join(f'{m:.2f}' for m in mu)})"
                              for w, mu in zip(g.weights_, g.means_))
            lines.append(f"{name}: {int(self.counts[p - 1])} px, {comps}")
        return "\n".join(lines)


def fit_part_models(features: np.ndarray, labels: np.ndarray, n_parts: int, *, n_components: int = 3,
                    min_pixels: int = 30, max_pixels: int = 1500, covariance_type: str = "full",
                    reg_covar: float = 1e-4, space: str = "lab",
                    rng: np.random.Generator | int | None = 0) -> PartColourModels:
    """Fit one ``GaussianMixture`` per part to labelled pixel features.

    Parameters
    ----------
    features : ndarray of shape (N, D)
        Colour features of the confident pixels.
    labels : ndarray of shape (N,)
        Their part ids (1..n_parts).
    n_parts : int
    n_components : int
        Mixture components (fewer when a part has few pixels: at most one per
        ``min_pixels`` pixels).
    min_pixels : int
        Parts with fewer confident pixels get no model.
    max_pixels : int
        At most this many pixels per part are used (random subset from ``rng``).
    covariance_type, reg_covar
        As for :class:`sklearn.mixture.GaussianMixture`.
    space : str
        Recorded in the result.
    rng : numpy.random.Generator or int or None
        Subsampling and mixture initialisation.

    Returns
    -------
    PartColourModels
    """
    f = np.asarray(features, np.float64)
    lab = np.asarray(labels)
    if f.ndim != 2 or lab.shape != (len(f),):
        raise InputError("fit_part_models: features, labels", "(N, D) and (N,)", f"{f.shape} and {lab.shape}")
    if n_components < 1:
        raise InputError("fit_part_models: n_components", "at least 1", repr(n_components))
    rng = np.random.default_rng(rng)
    models = {}
    counts = np.zeros(n_parts, int)
    for p in range(1, n_parts + 1):
        idx = np.flatnonzero(lab == p)
        counts[p - 1] = len(idx)
        if len(idx) < min_pixels:
            continue
        if len(idx) > max_pixels:
            idx = rng.choice(idx, max_pixels, replace=False)
        distinct = len(np.unique(np.round(f[idx], 4), axis=0))  # a one-colour part gets one component
        k = int(max(1, min(n_components, len(idx) // min_pixels, distinct)))
        g = GaussianMixture(k, covariance_type=covariance_type, reg_covar=reg_covar, max_iter=50,
                            random_state=int(rng.integers(2**31)))
        # an EM run stopped at max_iter still gives a usable model (the best initialisation is kept)
        with _one_thread(), warnings.catch_warnings():
            warnings.simplefilter("ignore", ConvergenceWarning)
            g.fit(f[idx])
        models[p] = g
    return PartColourModels(models, int(n_parts), counts, space)
