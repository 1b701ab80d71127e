"""Files of snapshots ("frames"): a run's lattices at several steps, and those steps.

    save_frames("run_frames.npz", frames, steps, states=3)   # the automata's --frames files
    frames, steps, meta = load_frames("run_frames.npz")

`frames` holds one lattice per snapshot along `frame_axis`: 0, or 1 when a leading axis
stacks several runs (one row of snapshots each, described by the metadata's `runs`);
`steps` holds the step of each snapshot, increasing. Like every file kind, the JSON
metadata records the morphojax version and the format number (`_files.stamp`); it also
says what the arrays hold (their count, shape and dtype, the number of states), and
`load_frames` checks every field against the arrays through one validator
(`check_frames`), so a file whose metadata disagrees with itself or its arrays is refused
with the field named, and a file from a newer morphojax warns, naming both versions.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from ._checks import STEP_COUNTER_MAX
from ._files import read_npz, to_jsonable, write_npz

FORMAT = "morphojax-frames/1"


def save_frames(path, frames, steps, *, frame_axis: int = 0, states: int | None = None, runs=None,
                metadata: dict | None = None) -> Path:
    """Write `frames` (snapshots along `frame_axis`) and their `steps` to `path` (.npz added if
    missing), atomically, with checked metadata: `states` (cell values lie in 0 .. states - 1),
    `runs` (one JSON entry per run when `frame_axis` is 1) and any JSON-able `metadata`. What
    `load_frames` would refuse is refused here, before anything is written."""
    frames, steps = np.asarray(frames), np.asarray(steps)
    meta = {**(metadata or {}), "format": FORMAT, "count": int(steps.size), "frame_axis": frame_axis,
            "shape": list(frames.shape), "dtype": str(frames.dtype)}
    if states is not None:
        meta["states"] = states
    if runs is not None:
        meta["runs"] = list(runs)
    meta = to_jsonable(meta)
    check_frames(meta, frames, steps)
    return write_npz(path, frames=frames, steps=steps, metadata=np.asarray(json.dumps(meta)))


def load_frames(path) -> tuple[np.ndarray, np.ndarray, dict]:
    """(frames, steps, metadata) from a file written by `save_frames`; a damaged file, or one
    whose metadata disagrees with itself or its arrays, is a ValueError naming the file and
    the field."""

    def parse(meta, data):
        return np.asarray(data["frames"]), np.asarray(data["steps"])

    meta, (frames, steps) = read_npz(path, "frames", parse)
    try:
        check_frames(meta, frames, steps)
    except (KeyError, TypeError, IndexError, ValueError, OverflowError) as err:
        why = f"no {err.args[0]!r} entry" if isinstance(err, KeyError) else str(err)
        raise ValueError(f"{path} is not a valid morphojax frames file ({why})") from None
    return frames, steps, meta


def _int_field(meta, field, low, high=None):
    value = meta.get(field)
    if isinstance(value, bool) or not isinstance(value, int) or value < low or (high is not None and value > high):
        limits = f">= {low}" if high is None else f"in [{low}, {high}]"
        raise ValueError(f"metadata field {field!r} must be an integer {limits} (got {value!r})")
    return value


def check_frames(meta: dict, frames: np.ndarray, steps: np.ndarray) -> None:
    """Raise ValueError, naming the field, when the metadata of a frames file disagrees with
    itself or with its arrays (`frames`, `steps`)."""
    if meta.get("format") != FORMAT:
        raise ValueError(f"metadata field 'format' is {meta.get('format')!r}, expected {FORMAT!r}")
    if frames.dtype.kind not in "biuf":
        raise ValueError(f"its array 'frames' holds {frames.dtype}, not numbers")
    axis = _int_field(meta, "frame_axis", 0, 1)
    if frames.ndim < axis + 2:  # a lattice of at least one axis after the frame axis
        raise ValueError(f"its array 'frames' has shape {frames.shape}: no lattice after the frame axis {axis}")
    if meta.get("shape") != list(frames.shape):
        raise ValueError(f"metadata field 'shape' is {meta.get('shape')!r} but its frames have shape "
                         f"{list(frames.shape)}")
    if meta.get("dtype") != str(frames.dtype):
        raise ValueError(f"metadata field 'dtype' is {meta.get('dtype')!r} but its frames hold {frames.dtype}")
    count = _int_field(meta, "count", 0)
    if count != frames.shape[axis]:
        raise ValueError(f"metadata field 'count' is {count} but its frames hold {frames.shape[axis]} snapshots "
                         f"along axis {axis}")
    # the steps: one per snapshot, whole, within the int32 step counter, increasing
    if steps.shape != (count,) or steps.dtype.kind not in "iu":
        raise ValueError(f"its array 'steps' must hold {count} integers, one per snapshot (got {steps.dtype} of "
                         f"shape {steps.shape})")
    if count and not (steps.min() >= 0 and steps.max() <= STEP_COUNTER_MAX):
        raise ValueError(f"its array 'steps' must lie in [0, {STEP_COUNTER_MAX}] (got {steps.min()} .. "
                         f"{steps.max()})")
    if (np.diff(steps.astype(np.int64)) <= 0).any():
        raise ValueError(f"its array 'steps' must increase (got {steps.tolist()[:8]}{' ...' if count > 8 else ''})")
    if "states" in meta:
        states = _int_field(meta, "states", 1)
        if frames.size and (frames.min() < 0 or frames.max() >= states):
            raise ValueError(f"metadata field 'states' is {states} but its frames hold values {frames.min()} .. "
                             f"{frames.max()}, outside 0 .. {states - 1}")
    if axis == 1:
        runs = meta.get("runs")
        if not isinstance(runs, list) or len(runs) != frames.shape[0]:
            raise ValueError(f"metadata field 'runs' must list one entry per run: its frames hold {frames.shape[0]} "
                             f"runs along their first axis (got {runs!r})")
    elif "runs" in meta:
        raise ValueError("metadata field 'runs' is given but 'frame_axis' is 0 (the frames of one run)")
