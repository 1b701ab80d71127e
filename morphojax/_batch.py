"""The batched execution of a sweep: one compiled program over chunks of members, on devices.

A chunk of members runs as one compiled program (`_batch_program`): each member builds its
model from traced parameter values (`member_model`), so the same program serves every value
and every chunk. Members are processed in chunks of `batch_size` (the last chunk is padded
with copies of the last member, so every chunk reuses the same program and memory stays
bounded); each chunk's batch axis is sharded over a `jax.sharding.Mesh` of devices
(`devices=None`: all local devices), so the same call uses one CPU, 8 GPUs or a TPU slice.

On GPUs, TPUs and several devices a chunk is one vmap. On a single CPU device the members
of a chunk run group after group inside the program (`lax.map`): a group of 8 members in
the vector lanes of one array where the members allow it (`_lanes`), else one member at a
time, so each group's lattices stay in cache; one thread per core runs chunks side by side:
coarse-grained parallelism with no per-step hand-off, where a wide vmap would stream the
whole chunk through memory at every step (figures in benchmarks/results/bench_sweep.md). A member that blows up is
recorded (its first non-finite step), never raised.

Several hosts. Call `jax.distributed.initialize()` in every process first (it finds the
coordinator on Cloud TPU, SLURM and similar; elsewhere pass `coordinator_address`,
`num_processes` and `process_id`), then call `sweep` with the same arguments in every
process. Each process runs a contiguous block of the members on its own local devices,
and the final arrays are all-gathered (`multihost_utils.process_allgather`), so every
process returns the full result; write files from process 0 only.
"""

from __future__ import annotations

import dataclasses
import os
import time
from concurrent.futures import ThreadPoolExecutor

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec

from ._descriptors import relative_change
from ._lanes import NOT_LOCATED, lane_count, lanes_apply, run_group
from ._simulate import run_status
from .solvers import Euler
from ._sweep_members import member_model

# Lattice values per device in one chunk (the default `batch_size`): a bound on memory.
_BUDGET = {"cpu": 1 << 19, "other": 1 << 25}
_MAX_WORKERS = 8  # threads running chunks side by side on a single CPU device, at most
_TRACES = {"batch": 0}  # times the batched program was traced (tests guard against recompiles)


# ---- the batched program ---------------------------------------------------------------------
def _member_run(model, growth, sources, state, key, values, dt, *, steps, tail, boundary, stencil, bounds, solver,
                until=None):
    """One member (traced; vmapped by `_batch_program`): build its model, run, measure the last steps."""
    m, g, dt = member_model(model, growth, dt, values)
    kw = dict(stencil=stencil, bounds=bounds, growth=g, sources=sources, key=key, check_dt=False,
              origin=state.step, solver=solver, until=until)
    mid, bad, overflow = run_status(m, state, steps - tail, dt, boundary, **kw)
    if tail == 0:
        return mid, bad, overflow, jnp.asarray(jnp.nan, mid.fields.dtype)
    final, bad2, overflow2 = run_status(m, mid, tail, dt, boundary, **kw)
    change = relative_change(mid.fields, final.fields, xp=jnp)
    return final, jnp.where(bad >= 0, bad, bad2), overflow | overflow2, change


def _batch_program(model, growth, sources, state, keys, values, dt, *, state_axis, steps, tail, boundary, stencil,
                   bounds, inner, lanes, out_sharding, solver=None, until=None):
    """A chunk of members: (fields, size, bad step, overflow, change), each with a leading
    member axis. With `lanes`, groups of `inner` members in lanes (`_lanes.run_group`), one
    group after another; else vmapped `inner` at a time (`lax.map` runs the sub-batches in
    sequence)."""
    _TRACES["batch"] += 1  # runs at trace time only
    size = len(next(iter(values.values())))
    kw = dict(steps=steps, tail=tail, boundary=boundary, stencil=stencil, bounds=bounds)
    if lanes:  # lanes step with forward Euler only (`run_batched` chooses them for Euler alone)
        first = (lambda a: a) if state_axis is None else (lambda a: a[0])  # every start has one size and step

        def group(x):
            fields = state.fields if state_axis is None else x[0]
            return run_group(model, fields, first(state.size), first(state.step), x[1], dt, **kw)

        split = lambda a: a.reshape((size // inner, inner) + a.shape[1:])  # noqa: E731
        xs = (None if state_axis is None else split(state.fields), jax.tree_util.tree_map(split, values))
        out = jax.lax.map(group, xs)
        out = tuple(a.reshape((size,) + a.shape[2:]) for a in out)
    else:
        def one(state, key, values):
            final, bad, over, change = _member_run(model, growth, sources, state, key, values, dt, solver=solver,
                                                   until=until, **kw)
            return final.fields, final.size, bad, over, change

        if inner >= size:
            out = jax.vmap(one, in_axes=(state_axis, None if keys is None else 0, 0))(state, keys, values)
        else:
            xs = (state if state_axis == 0 else None, keys, values)

            def each(x):
                return one(state if state_axis is None else x[0], x[1], x[2])

            out = jax.lax.map(each, xs, batch_size=None if inner == 1 else inner)
    if out_sharding is not None:  # keep every output split along the batch axis
        out = jax.tree_util.tree_map(lambda x: jax.lax.with_sharding_constraint(x, out_sharding), out)
    return out


_run_batch = eqx.filter_jit(_batch_program)


# ---- devices, chunks, threads and hosts -----------------------------------------------------
def _devices(devices):
    if devices is None:
        return list(jax.local_devices())
    if isinstance(devices, int):
        local = jax.local_devices()
        if not 1 <= devices <= len(local):
            raise ValueError(f"sweep: devices={devices} but this process has {len(local)} local device(s)")
        return list(local[:devices])
    devices = list(devices)
    if not devices:
        raise ValueError("sweep: devices is an empty list; pass None for all local devices")
    return devices


def _chunk_size(batch_size, n, per_member, devices):
    ndev = len(devices)
    if batch_size is None:
        budget = _BUDGET["cpu" if devices[0].platform == "cpu" else "other"]
        size = min(n, max(1, budget // max(per_member, 1)) * ndev)
        workers = _workers(devices, n)
        if workers > 1:  # one chunk per worker at least, so every core has members to run
            size = min(size, -(-n // workers))
    else:
        if not isinstance(batch_size, (int, np.integer)) or isinstance(batch_size, bool) or batch_size < 1:
            raise ValueError(f"sweep: batch_size must be a positive integer or None (got {batch_size!r})")
        size = min(int(batch_size), n)
    return -(-size // ndev) * ndev  # a multiple of the number of devices


def _workers(devices, n_members) -> int:
    """Threads dispatching chunks at once: the CPU cores for a single CPU device, else 1."""
    if len(devices) > 1 or devices[0].platform != "cpu":
        return 1
    return max(1, min(os.cpu_count() or 1, _MAX_WORKERS, n_members))


def _layout(vmap_size, devices, chunk, lanes: int) -> tuple[int, bool]:
    """(members advanced together by one step, whether they run in lanes). `lanes`: the
    group size when the members can run in lanes (`_lanes.lanes_apply`), else 0."""
    if vmap_size is not None:
        if not isinstance(vmap_size, (int, np.integer)) or isinstance(vmap_size, bool) or vmap_size < 1:
            raise ValueError(f"sweep: vmap_size must be a positive integer or None (got {vmap_size!r})")
        return min(int(vmap_size), chunk), False
    if len(devices) == 1 and devices[0].platform == "cpu":
        # CPU: a group in lanes, or one member at a time, stays in cache; the cores run
        # chunks side by side. Groups always hold `lanes` members, so that a member's bits
        # do not depend on the chunking (nor on the number of processes)
        return (lanes, True) if lanes else (1, False)
    return chunk, False


def _host_block(n, index, count):
    """The contiguous members [start, stop) that process `index` of `count` runs (equal padded blocks)."""
    per = -(-n // count)
    return min(index * per, n), min((index + 1) * per, n), per


# ---- running the chunks -----------------------------------------------------------------------
@dataclasses.dataclass
class BatchRun:
    """What the batched execution gives back: host arrays over the members, and how it ran."""

    fields: np.ndarray  # (n, species, *capacity) final concentrations
    size: np.ndarray  # (n, 2) active lattice
    blowup_step: np.ndarray  # (n,) first non-finite step or -1
    overflow: np.ndarray  # (n,) growth wanted more than the capacity
    change: np.ndarray  # (n,) relative change over the last `tail` steps
    member_devices: np.ndarray  # (n,) id of the device that computed each member
    sharding: str  # the batch sharding (or the one device)
    devices: list  # the devices of this process that ran chunks
    chunk: int  # members per compiled chunk
    inner: int  # members advanced together by one step
    lanes: bool  # the members of a group shared the step's vector lanes (`_lanes`)
    seconds: float  # wall time of the chunks (and the gather between hosts)


def run_batched(model, growth, sources, starts, member_keys, values, dt, *, steps, tail, boundary, stencil, bounds,
                batch_size, devices, vmap_size, progress, solver=None, until=None) -> BatchRun:
    """Run every member of `values` ({name: (n,) array}) in chunks over `devices` (and hosts).

    `starts` gives the members' initial states (`chunk(idx, member_keys)`, `shared`, `state`,
    `probe`); `member_keys` is (n,) keys or None. With `devices=None` and several processes,
    each process runs its block of members and the blocks are all-gathered.
    """
    n = len(next(iter(values.values())))
    probe = starts.probe
    devs = _devices(devices)
    hosts = devices is None and jax.process_count() > 1  # split the members between processes
    lo, hi, per_host = _host_block(n, jax.process_index(), jax.process_count()) if hosts else (0, n, n)
    chunk = _chunk_size(batch_size, max(per_host, 1), int(np.prod(probe.fields.shape)), devs)
    euler = solver is None or isinstance(solver, Euler)
    plain = euler and until is None  # lanes step forward Euler for a fixed count
    group = lane_count(probe.fields.dtype) if plain and lanes_apply(model, growth, sources, probe) else 0
    inner, lanes = _layout(vmap_size, devs, chunk, group)
    if lanes:  # whole groups (padded like the last chunk)
        chunk = -(-chunk // inner) * inner
    t0 = time.perf_counter()
    host, sharding = _run_chunks(
        model, growth, sources, starts, member_keys, values, jnp.asarray(dt, probe.fields.dtype), devs, chunk, lo, hi,
        dict(steps=steps, tail=tail, boundary=boundary, stencil=stencil, bounds=bounds, inner=inner, lanes=lanes,
             solver=solver, until=until),
        progress)
    if hosts:
        host = _gather_hosts(host, n, per_host)
    fields, size, bad, over, change, member_devices = host
    seconds = time.perf_counter() - t0
    return BatchRun(fields, size, bad, over, change, member_devices, sharding, devs, chunk, inner, lanes, seconds)


def _run_chunks(model, growth, sources, starts, member_keys, values, dt, devs, chunk, lo, hi, static, progress):
    """Members lo..hi-1 in chunks of `chunk`, each sharded over `devs`; host arrays and the sharding.

    On a single CPU device, `_workers` threads run chunks side by side (the program is traced
    and compiled once beforehand, so the threads only find it in the cache; XLA:CPU runs a
    call in its caller's thread). Otherwise chunks are dispatched in order, each copied back
    to the host while the next one computes.
    """
    mesh = Mesh(np.asarray(devs), ("batch",))
    batch, replicated = NamedSharding(mesh, PartitionSpec("batch")), NamedSharding(mesh, PartitionSpec())
    dtype = starts.probe.fields.dtype
    values = {k: np.asarray(v, dtype) for k, v in values.items()}
    shared = (model, growth, sources, starts.state if starts.shared else None, dt)
    model, growth, sources, shared_state, dt = jax.device_put(shared, replicated)
    static = static | dict(out_sharding=batch if len(devs) > 1 else None)
    put = lambda tree: jax.device_put(tree, batch)  # noqa: E731

    def inputs(a):
        idx = np.minimum(np.arange(a, a + chunk), min(a + chunk, hi) - 1)  # the last chunk is padded
        state, axis = starts.chunk(idx, member_keys)
        state = shared_state if axis is None else put(state)
        keys = None if member_keys is None else put(jax.vmap(lambda k: jax.random.fold_in(k, 1))(member_keys[idx]))
        vals = put({k: v[idx] for k, v in values.items()})
        return (model, growth, sources, state, keys, vals, dt), dict(state_axis=axis, **static)

    def launch(a):
        args, kwargs = inputs(a)
        return _run_batch(*args, **kwargs), a, min(a + chunk, hi)

    def to_host(item):
        arrays, a, b = item
        if static["lanes"] and (np.asarray(arrays[2])[: b - a] == NOT_LOCATED).any():
            # a member went non-finite: the chunk again member by member, which finds the
            # exact first bad step (as a lone run does)
            args, kwargs = inputs(a)
            arrays = _run_batch(*args, **(kwargs | dict(lanes=False, inner=1)))
        return a, tuple(np.asarray(x)[: b - a] for x in arrays) + (_owners(arrays[0], b - a),)

    firsts = list(range(lo, hi, chunk))
    workers = min(_workers(devs, hi - lo), len(firsts))
    parts = []
    bar = None
    if progress and firsts:
        from ._progress import progress_bar

        bar = progress_bar(hi - lo, "sweep", unit="member")

    def done(part):
        parts.append(part)
        if bar is not None:
            bar.update(len(part[1][0]))

    try:
        if workers > 1:
            args, kwargs = inputs(firsts[0])
            _run_batch.lower(*args, **kwargs).compile()  # trace and compile once, before the threads
            with ThreadPoolExecutor(workers) as pool:
                for part in pool.map(lambda a: to_host(launch(a)), firsts):
                    done(part)
        else:
            pending = []
            for a in firsts:
                pending.append(launch(a))
                if len(pending) > 1:  # copy the previous chunk to the host while this one computes
                    done(to_host(pending.pop(0)))
            while pending:
                done(to_host(pending.pop(0)))
    finally:
        if bar is not None:
            bar.close()
    if parts:
        parts.sort(key=lambda p: p[0])
        host = tuple(np.concatenate(p) for p in zip(*(arrays for _, arrays in parts)))
    else:
        cap = starts.probe.fields.shape
        host = (np.zeros((0,) + cap, dtype), np.zeros((0, 2), np.int32), np.zeros(0, np.int32), np.zeros(0, bool),
                np.zeros(0, dtype), np.zeros(0, int))
    return host, (str(batch) if len(devs) > 1 else str(devs[0]))


def _owners(arr, count) -> np.ndarray:
    """Device id of each of the first `count` members of a batch-sharded array."""
    owner = np.full(arr.shape[0], -1)
    for shard in arr.addressable_shards:
        owner[shard.index[0]] = shard.device.id
    return owner[:count]


def _gather_hosts(parts, n, per_host):
    """All-gather every process's block of members (multi-host runs; equal padded blocks)."""
    from jax.experimental import multihost_utils

    out = []
    for x in parts:  # pad to equal blocks (a process may hold fewer members, or none)
        x = np.concatenate([x, np.zeros((per_host - len(x),) + x.shape[1:], x.dtype)])
        g = np.asarray(multihost_utils.process_allgather(x))
        out.append(g.reshape((-1,) + g.shape[2:])[:n])
    return out
