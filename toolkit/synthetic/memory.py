"""How much memory rendering a scene spec takes, checked before anything is allocated.

The ray caster (:class:`toolkit.synthetic.render.RaycastRenderer`) holds a
whole image's sub-pixel rays at once: ``width * height * supersample**2``
rays of origins, directions, hits, normals and texture coordinates.  An
8192 x 8192 spec with ``supersample = 4`` is a billion rays, which no
workstation holds; :func:`check_render_memory` refuses such a spec with the
estimate before the first frame, instead of letting it run until the
operating system kills it.

The figures were measured with ``/usr/bin/time -f %M`` on
``recipes/make_scene.py`` (``datasets_synthetic/tiny.toml``, one frame, no
novel views, 2026-11-29): peak RSS 444 MB at 320 x 180 with supersample 1,
803 MB at 640 x 360 and 2047 MB at 1280 x 720 with supersample 4, i.e.
112 bytes per sub-pixel ray over a 440 MB base.
"""

from __future__ import annotations

import os

from toolkit.errors import InputError

__all__ = ["BASE_BYTES", "RAY_BYTES", "available_memory", "check_render_memory", "render_bytes"]

#: Peak memory of the generator apart from the rays (Python, Open3D, the scene's meshes), bytes.
BASE_BYTES = 450 << 20
#: Peak memory per sub-pixel ray of one rendered image, bytes (112 measured, rounded up).
RAY_BYTES = 120


def render_bytes(resolution, supersample: int) -> int:
    """Estimated peak memory of rendering images of ``resolution`` (W, H) with ``supersample``, bytes."""
    w, h = (int(v) for v in resolution)
    return BASE_BYTES + RAY_BYTES * w * h * int(supersample) ** 2


def available_memory() -> int | None:
    """Memory this process may still take, bytes (``MemAvailable`` on Linux, else physical memory; None unknown)."""
    try:
        with open("/proc/meminfo", encoding="ascii") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_PHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def check_render_memory(spec, available: int | None = None) -> int:
    """Refuse a colour scene spec whose rendering would not fit in memory; return the estimate, bytes.

    Parameters
    ----------
    spec : SceneSpec
        A parsed spec (its ``resolution``, ``supersample`` and ``source``).
    available : int, optional
        Bytes available (default :func:`available_memory`; unknown: no check).

    Raises
    ------
    InputError
        The estimate exceeds the memory available, naming the spec's resolution and supersample.
    """
    need = render_bytes(spec.resolution, spec.supersample)
    available = available_memory() if available is None else available
    if available is not None and need > available:
        w, h = spec.resolution
        raise InputError(f"{spec.source}: cameras.resolution / render.supersample",
                         f"a rendering that fits in the {available / 2**30:.1f} GiB of memory available",
                         f"{w} x {h} with supersample {spec.supersample}: about {need / 2**30:.1f} GiB "
                         f"({RAY_BYTES} bytes per sub-pixel ray); lower the resolution or the supersampling")
    return need
