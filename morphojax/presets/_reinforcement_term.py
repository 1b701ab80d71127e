"""The leopard paper's Fig. 7: the reinforcement term's plot, `morphojax run reinforcement-term`.

Fig. 7 plots eq. 6's reaction, gamma (t - w - c)(t - c)(t + w - c) with gamma =
3 sqrt(3) / (2 w^2), for t = 1 and w = 1, its roots marked by circles and its local minimum
and maximum by downward and upward triangles. The preset draws `mj.Reinforcement`'s own
`reaction` over [t - 1.25 w, t + 1.25 w] and reads every mark from it (`term_marks`): the
roots where the reaction changes sign, the extrema where its derivative (`jax.grad` of the
reaction) does, each refined by bisection. The section states where they must fall: roots at
t - w, t and t + w, the minimum -w and the maximum +w (at t -+ w / sqrt(3)). The summary
gives the marks as drawn, read back from the plot's markers. No run: the figure is a plot.
"""

from __future__ import annotations

import io

import jax
import jax.numpy as jnp
import numpy as np

from ..models import Reinforcement
from ._registry import AutomatonPreset, registered

FIG7 = {"threshold": 1.0, "width": 1.0}  # the caption's t and w
SPAN = 1.25  # the plot runs over [t - SPAN w, t + SPAN w]
MARKERS = {"root": "o", "minimum": "v", "maximum": "^"}  # the caption's circles and triangles


def _bisect(f, a: float, b: float, steps: int = 60) -> float:
    """The sign change of `f` in [a, b] (f(a) and f(b) of opposite signs)."""
    fa = np.sign(f(a))
    for _ in range(steps):
        m = 0.5 * (a + b)
        if np.sign(f(m)) == fa:
            a = m
        else:
            b = m
    return 0.5 * (a + b)


def term_marks(model: Reinforcement, lo: float, hi: float, samples: int = 1000) -> dict:
    """The roots and local extrema of `model.reaction` on [lo, hi], read from the model.

    The reaction is sampled at the midpoints of `samples` equal parts (so that round roots
    fall between them); each sign change of the reaction is a root, refined by bisection,
    with `attracts` when the reaction falls through zero there; each sign change of its
    derivative (`jax.grad`) is a minimum (the derivative rises through zero) or a maximum,
    with the reaction's value there as `rate`. Positions and rates are Python floats."""
    def rate(c):
        return model.reaction(jnp.reshape(jnp.asarray(c, jnp.result_type(float)), (1,)))[0]

    slope = jax.jit(jax.grad(rate))
    rate_at = jax.jit(rate)
    x = lo + (np.arange(samples) + 0.5) * (hi - lo) / samples
    y = np.asarray(jax.vmap(rate_at)(jnp.asarray(x)))
    dy = np.asarray(jax.vmap(slope)(jnp.asarray(x)))
    out = {"root": [], "minimum": [], "maximum": []}
    for i in np.flatnonzero(np.sign(y[:-1]) * np.sign(y[1:]) < 0):
        at = _bisect(lambda c: float(rate_at(c)), x[i], x[i + 1])
        out["root"].append({"at": at + 0.0, "attracts": bool(y[i] > 0)})  # + 0.0: no -0.0
    for i in np.flatnonzero(np.sign(dy[:-1]) * np.sign(dy[1:]) < 0):
        at = _bisect(lambda c: float(slope(c)), x[i], x[i + 1])
        out["minimum" if dy[i] < 0 else "maximum"].append({"at": at, "rate": float(rate_at(at))})
    return out


def plot_term(model: Reinforcement, marks: dict, lo: float, hi: float, height: int = 400):
    """The reaction on [lo, hi] with `marks` (`term_marks`) drawn: roots as red circles,
    the minimum and maximum as green downward and upward triangles (Fig. 7's caption).
    Returns the picture and the marks read back from the plot's markers, kind -> [(x, y)]."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from PIL import Image

    x = np.linspace(lo, hi, 601)
    y = np.asarray(jax.vmap(lambda c: model.reaction(c[None])[0])(jnp.asarray(x)))
    fig, ax = plt.subplots(figsize=(5.0, 4.0), dpi=height / 4.0)
    ax.axhline(0.0, color="0.6", lw=0.8)
    ax.plot(x, y, color="black")
    for root in marks["root"]:
        ax.plot(root["at"], 0.0, MARKERS["root"], color="red", mfc="red" if root["attracts"] else "white", ms=8)
    for kind in ("minimum", "maximum"):
        for point in marks[kind]:
            ax.plot(point["at"], point["rate"], MARKERS[kind], color="green", ms=9)
    t, w = (float(np.ravel(np.asarray(v))[0]) for v in (model.threshold, model.width))
    ax.set_xlabel("c")
    ax.set_ylabel("dc/dt (reaction)")
    ax.set_title(f"gamma (t - w - c)(t - c)(t + w - c), t = {t:g}, w = {w:g}", fontsize=9)
    drawn = {kind: [(float(line.get_xdata()[0]), float(line.get_ydata()[0]))
                    for line in ax.lines if line.get_marker() == marker] for kind, marker in MARKERS.items()}
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png")
    plt.close(fig)
    buffer.seek(0)
    return Image.open(buffer).convert("RGB"), drawn


@registered(AutomatonPreset, "reinforcement-term", "eq. 6's reinforcement term for t = 1, w = 1 plotted from "
            "mj.Reinforcement, its roots (circles, filled where they attract) and its minimum and maximum "
            "(triangles) read from the model", "leopard paper Fig. 7")
def _reinforcement_term(seed, quick, out, frames):
    """Fig. 7 (no run: `seed`, `quick` and `frames` change nothing)."""
    model = Reinforcement(**FIG7)
    t, w = FIG7["threshold"], FIG7["width"]
    lo, hi = t - SPAN * w, t + SPAN * w
    marks = term_marks(model, lo, hi)
    picture, drawn = plot_term(model, marks, lo, hi)
    picture.save(out)
    rounded = {kind: [{k: round(v, 6) if isinstance(v, float) else v for k, v in p.items()} for p in points]
               for kind, points in marks.items()}
    return {"model": {"threshold": t, "width": w, "gamma": float(model.gamma)}, "range": [lo, hi], **rounded,
            "drawn": {kind: [[round(x, 6), round(y, 6)] for x, y in points] for kind, points in drawn.items()},
            "files": [str(out)]}


__all__ = ["plot_term", "term_marks"]
