"""Fit reports: region statistics (scikit-image) and the side-by-side preview picture."""

from __future__ import annotations

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from ._palette import GREY, colourise, unit


def region_stats(field, thresh=None) -> dict:
    """Non-differentiable statistics of the bright (pigment-high) phase: spots per 1000 cells,
    area distribution, mean eccentricity, Euler number; plus the dark fraction."""
    from skimage.filters import threshold_otsu
    from skimage.measure import euler_number, label, regionprops

    x = np.asarray(field, float)
    if np.ptp(x) == 0:
        return {"spots_per_1000_cells": 0.0, "dark_fraction": 1.0, "area_mean": 0.0, "area_median": 0.0,
                "area_q25": 0.0, "area_q75": 0.0, "eccentricity_mean": 0.0, "euler_number": 0}
    t = threshold_otsu(x) if thresh is None else thresh
    mask = x >= t
    lab = label(mask, connectivity=2)
    props = regionprops(lab)
    areas = np.array([p.area for p in props], float)
    ecc = np.array([p.eccentricity for p in props if p.area >= 3], float)
    q = np.quantile(areas, [0.25, 0.5, 0.75]) if len(areas) else np.zeros(3)
    return {
        "spots_per_1000_cells": 1000.0 * len(areas) / x.size,
        "dark_fraction": float((~mask).mean()),
        "area_mean": float(areas.mean()) if len(areas) else 0.0,
        "area_median": float(q[1]), "area_q25": float(q[0]), "area_q75": float(q[2]),
        "eccentricity_mean": float(ecc.mean()) if len(ecc) else 0.0,
        "euler_number": int(euler_number(mask, connectivity=2)),
    }


def describe(result) -> str:
    """The fit in words: family, parameters with intervals, undetermined ones, distance to the floor."""
    parts = [result.verdict + "." if result.verdict else "", f"family {result.family or '?'}:"]
    for name, value in result.params.items():
        text = f"{name} = {value:.3g}"
        if name in result.intervals:
            lo, hi = result.intervals[name]
            if np.isfinite(lo) and np.isfinite(hi):
                text += f" (95% interval {lo:.3g} to {hi:.3g})"
        parts.append(text + ("," if name != list(result.params)[-1] else ";"))
    if result.correlated:
        parts.append(f"moving together: {', '.join(' and '.join(p) for p in result.correlated)};")
    if result.undetermined:
        parts.append(f"not determined by the target: {', '.join(result.undetermined)};")
    else:
        parts.append("every fitted parameter is determined;")
    if result.noise_floor > 0:
        parts.append(f"loss {result.loss:.3g} = {result.loss / result.noise_floor:.1f}x the noise floor "
                     f"({result.noise_floor:.3g}).")
    return " ".join(p for p in parts if p)


def _gray(x, size):
    x = np.asarray(x, float)
    lo, hi = np.quantile(x, [0.02, 0.98])
    z = np.clip((x - lo) / max(hi - lo, 1e-9), 0, 1)
    img = Image.fromarray((z * 255).astype(np.uint8), "L").convert("RGB")
    return img.resize(size, Image.NEAREST)


def loss_curve(history, size=(256, 256)) -> Image.Image:
    """The loss of every evaluation (log scale), design points then local searches."""
    w, h = size
    img = Image.new("RGB", size, "white")
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default()
    losses = np.array([row["loss"] for row in history], float)
    losses = losses[np.isfinite(losses) & (losses > 0)]
    if len(losses) == 0:
        draw.text((8, 8), "no loss values", fill="black", font=font)
        return img
    logl = np.log10(losses)
    lo, hi = float(logl.min()), float(logl.max())
    span = max(hi - lo, 1e-9)
    left, right, top, bottom = 40, w - 8, 18, h - 22
    draw.rectangle([left, top, right, bottom], outline="gray")
    n = len(logl)
    pts = [(left + (right - left) * (i / max(n - 1, 1)), bottom - (bottom - top) * (v - lo) / span)
           for i, v in enumerate(logl)]
    stages = [row["stage"] for row in history if row["loss"] > 0 and np.isfinite(row["loss"])]
    for (x, y), st in zip(pts, stages):
        colour = (160, 160, 160) if st == "design" else (200, 60, 30)
        draw.ellipse([x - 1.5, y - 1.5, x + 1.5, y + 1.5], fill=colour)
    best = np.minimum.accumulate(logl)
    draw.line([(left + (right - left) * (i / max(n - 1, 1)), bottom - (bottom - top) * (v - lo) / span)
               for i, v in enumerate(best)], fill=(30, 60, 200), width=2)
    draw.text((4, 2), "log10 loss (grey: design, red: local, blue: best)", fill="black", font=font)
    draw.text((4, top), f"{hi:.1f}", fill="black", font=font)
    draw.text((4, bottom - 10), f"{lo:.1f}", fill="black", font=font)
    draw.text((left, bottom + 6), f"{n} evaluations", fill="black", font=font)
    return img


def _preview_lines(result, tf) -> list:
    """(text, colour) lines under the preview: the verdict (green when convincing, red when
    not), the parameters, resolution, loss and time, and the ranking with its reasons."""
    import textwrap

    lines = [(line, (0, 110, 0) if result.convincing else (170, 0, 0))
             for line in textwrap.wrap(result.verdict or "no verdict", 170)]
    lines.append((", ".join(f"{k} = {v:.3g}" + (f" [{result.intervals[k][0]:.3g}, {result.intervals[k][1]:.3g}]"
                                                  if k in result.intervals else "")
                            for k, v in result.params.items()), "black"))
    und = ", ".join(result.undetermined) if result.undetermined else "none"
    cp = result.target.get("cell_pixels")
    lines.append((f"not determined: {und}; {cp:.2f} photo pixels per cell, lattice {tf.shape[1]}x{tf.shape[0]}"
                  if cp else f"not determined: {und}", "black"))
    lines.append((f"loss {result.loss:.3g} (noise floor {result.noise_floor:.3g}), "
                  f"{result.timings.get('total', 0):.0f} s", "black"))
    for r in result.ranking[:6]:
        score = f"held-out {r['heldout']:.3f}" if "heldout" in r else f"screened, penalised loss {r['penalised']:.3g}"
        lines.append((f"  {r['family']}: {score}" + (f"; rejected: {r['rejected']}" if r.get("rejected") else ""),
                      "black"))
    return lines


def panel_sizes(target_shape, fit_shape, side: int) -> tuple:
    """(width, height) of the target's and the fit's panels, both at the same pixels per
    lattice cell, the wider `side` pixels wide: a fit on a smaller lattice than the target's
    is drawn smaller, so that its spots and stripes are seen at the target's scale (drawn at
    one width, a 64-cell fit of a 118-cell photo showed its pattern 1.8x too large)."""
    per_cell = side / max(target_shape[1], fit_shape[1])
    return tuple((max(1, round(s[1] * per_cell)), max(1, round(s[0] * per_cell))) for s in (target_shape, fit_shape))


def preview(result, scale: int | None = None) -> Image.Image:
    """target | fitted simulation | loss curve | the fit in the animal's colours, with the
    verdict, the fitted parameters, family, resolution, intervals and the ranking with its
    reasons underneath."""

    tf, ff = result.fields["target"], result.fields["fit"]
    side = 256
    tsize, fsize = panel_sizes(tf.shape, ff.shape, side)
    coat = Image.fromarray(colourise(unit(ff), result.palette or GREY), "RGB").resize(fsize, Image.BICUBIC)
    panels = [_gray(tf, tsize), _gray(ff, fsize), loss_curve(result.history, (side, side)), coat]
    lines = _preview_lines(result, tf)
    height = max(p.height for p in panels) + 24 + 13 * len(lines)
    canvas = Image.new("RGB", (4 * side + 20, height), "white")
    draw = ImageDraw.Draw(canvas)
    font = ImageFont.load_default()
    for k, (p, title) in enumerate(zip(panels, ["target", f"fit ({result.family}), same scale", "loss",
                                                "fit in the photo's colours"])):
        canvas.paste(p, (4 + k * (side + 4), 16))
        draw.text((4 + k * (side + 4), 2), title, fill="black", font=font)
    top = height - 13 * len(lines) - 2
    for i, (line, colour) in enumerate(lines):
        draw.text((4, top + 13 * i), line, fill=colour, font=font)
    return canvas
