"""Spatial prior from the projected template, and colour evidence to combine with it.

The ``"posterior"`` rule of :func:`toolkit.segmentation.segment_frame`
scores every part ``p`` at every uncertain pixel ``x`` with

    score_p(x) = max(e_p(x), -colour_cap)  -  d_p(x)^2 / (2 sigma^2)

* ``d_p`` is the pixel distance to part ``p``'s projected template
  (:func:`template_distances`) and ``sigma`` a fraction of the subject's
  image height: the expected error of the template's placement
  (:func:`spatial_log_prior`);
* ``e_p <= 0`` is the colour evidence against ``p``: the log-likelihood ratio of
  ``p``'s mixture to the best part's (:func:`colour_evidence`), or the
  calibrated version :func:`confusion_evidence`, which asks how often the
  confident pixels of ``p`` have the pixel's best mixture as their own best
  one (:func:`colour_confusion`), so that parts of one colour give each other
  no evidence; optionally averaged over a neighbourhood
  (:func:`smooth_evidence`).  Clipping at ``colour_cap`` nats keeps a colour no
  model explains (a shadow, a blend with the background) from outvoting the
  body's geometry.

It is a per-pixel maximum a posteriori label with a Gaussian position
likelihood and a floored colour likelihood.  Measured on a randomised zoo
(docs/stage2_segmentation.md) every variant was worse than the default
``colour_then_nearest`` rule: per pixel, the mixtures of parts that share a
colour still differ by shading, and that difference outvotes the template
near part borders.  The functions stay for the benchmark's sweep.
"""

from __future__ import annotations

import cv2
import numpy as np

from toolkit.errors import InputError


def template_distances(template_labels: np.ndarray, n_parts: int) -> np.ndarray:
    """Distance of every pixel to each part's projected template pixels.

    Parameters
    ----------
    template_labels : ndarray of shape (H, W), uint8
        Projected template part ids (0 = none).
    n_parts : int

    Returns
    -------
    ndarray of shape (H, W, n_parts), float32
        Euclidean pixel distance (0 on the part's own pixels); ``inf`` for a
        part the template does not show.
    """
    L = np.asarray(template_labels)
    if L.ndim != 2:
        raise InputError("template_distances: template_labels", "an (H, W) label image", f"shape {L.shape}")
    out = np.full(L.shape + (int(n_parts),), np.inf, np.float32)
    for p in range(1, int(n_parts) + 1):
        m = L == p
        if m.any():
            out[..., p - 1] = cv2.distanceTransform((~m).astype(np.uint8), cv2.DIST_L2, 5)
    return out


def colour_evidence(ll: np.ndarray, colour_cap: float) -> np.ndarray:
    """Colour log-likelihood ratio to the best part, clipped at ``-colour_cap``, (N, P).

    Parameters
    ----------
    ll : ndarray of shape (N, P)
        Colour log-likelihood per part, nats (``-inf`` = the part has no model).
    colour_cap : float
        Largest deficit counted, nats (>= 0).  A part without a model counts
        as ``colour_cap`` below the best (no colour evidence either way).

    Returns
    -------
    ndarray of shape (N, P), float32, values in [-colour_cap, 0]
    """
    ll = np.asarray(ll, float)
    if ll.ndim != 2:
        raise InputError("colour_evidence: ll", "an array of shape (N, P)", f"shape {ll.shape}")
    if not colour_cap >= 0:
        raise InputError("colour_evidence: colour_cap", ">= 0", repr(colour_cap))
    if ll.size == 0:
        return ll.astype(np.float32)
    top = ll.max(1, keepdims=True)
    top = np.where(np.isfinite(top), top, 0.0)
    return np.maximum(np.where(np.isfinite(ll), ll - top, -np.inf), -float(colour_cap)).astype(np.float32)


def smooth_evidence(evidence: np.ndarray, mask: np.ndarray, sigma_px: float) -> np.ndarray:
    """Gaussian average of per-pixel evidence over the pixels of ``mask`` (normalised convolution).

    Parameters
    ----------
    evidence : ndarray of shape (H, W, P), float32
        Values outside ``mask`` are ignored.
    mask : ndarray of shape (H, W), bool
    sigma_px : float
        Standard deviation of the Gaussian, pixels (0 = no smoothing).

    Returns
    -------
    ndarray of shape (H, W, P), float32
        Neighbouring pixels of one part share their colour evidence, so a
        lone pixel of the wrong shade does not flip.
    """
    E = np.asarray(evidence, np.float32)
    m = np.asarray(mask, bool)
    if E.ndim != 3 or m.shape != E.shape[:2]:
        raise InputError("smooth_evidence: evidence, mask", "shapes (H, W, P) and (H, W)", f"{E.shape} and {m.shape}")
    if sigma_px <= 0:
        return E.copy()
    w = m.astype(np.float32)
    k = int(2 * np.ceil(2.5 * sigma_px) + 1)
    den = cv2.GaussianBlur(w, (k, k), sigma_px)
    out = np.empty_like(E)
    for p in range(E.shape[2]):
        num = cv2.GaussianBlur(np.where(m, E[..., p], 0.0).astype(np.float32), (k, k), sigma_px)
        out[..., p] = num / np.maximum(den, 1e-6)
    return out


def spatial_log_prior(distances: np.ndarray, sigma_px: float) -> np.ndarray:
    """Gaussian log-prior of the template's placement error: ``-d^2 / (2 sigma^2)`` (``-inf`` at ``d = inf``).

    Parameters
    ----------
    distances : ndarray
        Pixel distances to a part's template.
    sigma_px : float
        Standard deviation, pixels (> 0).
    """
    if not sigma_px > 0:
        raise InputError("spatial_log_prior: sigma_px", "> 0", repr(sigma_px))
    d = np.asarray(distances, np.float32)
    return -(d * d) / np.float32(2.0 * float(sigma_px) ** 2)


def colour_confusion(ll: np.ndarray, labels: np.ndarray, n_parts: int, prior_count: float = 1.0) -> np.ndarray:
    """How often the colour models' best part is each part, per true part: a calibrated colour likelihood.

    Parameters
    ----------
    ll : ndarray of shape (N, P)
        Colour log-likelihood per part of pixels whose part is known (the
        confident pixels), nats (``-inf`` = the part has no model).
    labels : ndarray of shape (N,)
        Their part ids (1..n_parts).
    n_parts : int
    prior_count : float
        Pseudo-count added to every cell (Laplace smoothing): bounds the
        evidence of a colour never seen on a part to about
        ``log(prior_count / (pixels of the part + n_parts * prior_count))``.

    Returns
    -------
    ndarray of shape (n_parts, n_parts), float
        ``C[p, q]``: probability that a pixel of part ``p + 1`` has part ``q + 1``
        as its best colour model (rows sum to 1; a part without pixels has a
        uniform row).  Two parts of the same colour confuse each other (their
        rows are alike), so the colour says nothing between them; a part of
        its own colour has a peaked row.
    """
    ll = np.asarray(ll, float)
    lab = np.asarray(labels)
    if ll.ndim != 2 or ll.shape[1] != n_parts or lab.shape != (len(ll),):
        raise InputError("colour_confusion: ll, labels", f"(N, {n_parts}) and (N,)", f"{ll.shape} and {lab.shape}")
    counts = np.full((n_parts, n_parts), float(prior_count))
    if len(ll):
        best = ll.argmax(1)
        ok = (lab >= 1) & (lab <= n_parts) & np.isfinite(ll.max(1))
        np.add.at(counts, (lab[ok] - 1, best[ok]), 1.0)
    return counts / counts.sum(1, keepdims=True)


def confusion_evidence(ll: np.ndarray, confusion: np.ndarray) -> np.ndarray:
    """Log-likelihood of each part given the pixel's best colour model, relative to the best part, (N, P).

    Parameters
    ----------
    ll : ndarray of shape (N, P)
        Colour log-likelihood per part, nats.
    confusion : ndarray of shape (P, P)
        From :func:`colour_confusion`.

    Returns
    -------
    ndarray of shape (N, P), float32, <= 0
        ``log C[p, best(x)] - max_p' log C[p', best(x)]``; all zero where no part has a model.
    """
    ll = np.asarray(ll, float)
    C = np.asarray(confusion, float)
    if ll.ndim != 2 or C.shape != (ll.shape[1], ll.shape[1]):
        raise InputError("confusion_evidence: ll, confusion", "(N, P) and (P, P)", f"{ll.shape} and {C.shape}")
    logc = np.log(C.T)  # [best, part]
    logc = logc - logc.max(1, keepdims=True)
    out = logc[ll.argmax(1)] if len(ll) else np.zeros((0, C.shape[0]))
    out[~np.isfinite(ll.max(1)) if len(ll) else slice(0)] = 0.0
    return out.astype(np.float32)
