"""Animations: a run's snapshots as a GIF (Pillow) or an MP4 (imageio's ffmpeg plugin).

Every frame goes through the same colour range (the range of all frames together unless
`vmin`/`vmax` are given), so a rollout becomes a movie without flicker. The file is written
atomically (`_serialise.write_atomically`), so a crash keeps the last good one.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image

from ._render import to_image
from ._files import write_atomically

FORMATS = (".gif", ".mp4")


def _arrays(frames, species):
    """The frames as a list of 2D arrays (or PIL images, passed through)."""
    from ._state import State

    if isinstance(frames, State):  # a rollout's frames: a State with a leading frame axis
        index = frames.index(species) if species != -1 else frames.n_species - 1
        h, w = frames.shape
        return [np.asarray(frames.fields[i, index, :h, :w]) for i in range(frames.fields.shape[0])]
    out = [f if isinstance(f, Image.Image) else np.asarray(f) for f in frames]
    for i, f in enumerate(out):
        if not isinstance(f, Image.Image) and f.ndim != 2:
            raise ValueError(f"save_animation.frames[{i}] must be a 2D array or an image (got shape {f.shape})")
    return out


def save_animation(path, frames, *, cmap="inferno", vmin=None, vmax=None, scale: int = 1, fps: float = 10.0,
                   species=-1) -> Path:
    """Write `frames` as an animation to `path` (.gif, or .mp4 with imageio's ffmpeg plugin).

    Args:
        frames: 2D arrays, pillow images, or the frames `State` of `rollout` (then
            `species` picks the species shown, by name or index; default the last).
        cmap, vmin, vmax, scale: as `to_image`; the colour range defaults to the range of
            all frames together (one range for the whole movie).
        fps: frames per second.

    Returns the path written.
    """
    path = Path(path)
    if path.suffix.lower() not in FORMATS:
        raise ValueError(f"save_animation.path must end in one of {', '.join(FORMATS)} (got {path.name!r})")
    if not fps > 0:
        raise ValueError(f"save_animation.fps must lie in (0, +inf) (got {fps})")
    arrays = _arrays(frames, species)
    if not arrays:
        raise ValueError("save_animation.frames is empty")
    numeric = [a for a in arrays if not isinstance(a, Image.Image)]
    finite = [a[np.isfinite(a)] for a in numeric]
    values = np.concatenate(finite) if finite and any(v.size for v in finite) else np.zeros(1)
    lo = float(values.min()) if vmin is None else vmin
    hi = float(values.max()) if vmax is None else vmax
    images = [a.convert("RGB") if isinstance(a, Image.Image) else to_image(a, cmap, lo, hi, scale) for a in arrays]
    if path.suffix.lower() == ".gif":
        def write(tmp):
            images[0].save(tmp, format="GIF", save_all=True, append_images=images[1:], duration=round(1000 / fps),
                           loop=0)
    else:
        def write(tmp):
            _write_mp4(tmp, images, fps)
    return write_atomically(path, write)


def _write_mp4(path, images, fps):
    backend = "pyav" if _has("av") else "FFMPEG" if _has("imageio_ffmpeg") else None
    if not _has("imageio") or backend is None:
        raise ValueError("save_animation: MP4 needs imageio with an ffmpeg backend (pip install imageio[ffmpeg] "
                         "or imageio[pyav]); GIF works without it")
    import imageio.v3 as iio

    stack = np.stack([np.asarray(im) for im in images])
    stack = stack[:, : stack.shape[1] // 2 * 2, : stack.shape[2] // 2 * 2]  # H.264 wants even sides
    iio.imwrite(path, stack, fps=fps, plugin=backend, extension=".mp4")


def _has(module: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(module) is not None
