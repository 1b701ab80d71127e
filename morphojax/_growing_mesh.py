"""Growth on a triangle mesh: `MeshGrowth`, and the run that steps a growing mesh.

Matrix expansion (`Growth`) grows a lattice inside one compiled program. A mesh's growth
changes its operator (new cotangent weights, new neighbours), which is built in NumPy
(`domains._mesh_build`); so a growing mesh runs in compiled chunks between growth events,
and the events (scaling, dilution, division, the operator's rebuild: `domains._mesh_growth`)
run outside compiled code, between the chunks. The chunks keep one shape: the fields and
the operator's tables are padded to the state's vertex capacity, the active vertices
first (inactive ones held at zero by the active mask, as a growing lattice's cells).
A run with MeshGrowth is therefore eager: not under `jax.jit`, `vmap` or `grad`.
"""

from __future__ import annotations

import copy
import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jax import Array

from ._bounds import bounds_policy
from ._checks import as_float_array, check_choice, check_finite, check_range, is_concrete
from ._growth import steps_done
from ._loop import drive
from ._plan import WholeCapacity
from ._progress import progress_bar
from ._state import State
from ._status import RunStatus
from ._step import Config
from .domains import Mesh
from .domains._mesh_growth import MeshGeometry
from .solvers import as_solver

EDGES = ("random", "longest")
# the spectral radius the padded stepping meshes state (a static field: one value for the
# whole run, so the chunks compile once); the run checks dt against each rebuilt operator's
STATED_RHO = 1.0


class MeshGrowth(eqx.Module):
    """A growing surface: scaling of the mesh's vertices and division of its triangles.

    Growth events fall after every `every` steps of the phase (phase steps every, 2 every,
    ...). At each (see `domains/_mesh_growth.py` for the rules):

    1. every vertex moves away from the initial mesh's centroid by exp(rate * f_i * every
       * dt): lengths grow as exp(rate t), uniformly (`field=None`) or driven by a field f
       (one factor >= 0 per vertex of the initial mesh; a new vertex takes its parents' mean);
    2. with `dilute=True`, concentrations are divided by the growth of their vertex's area
       (each vertex keeps its mass M_i u_i); without, they are kept, and the mass grows with
       the area;
    3. with `divide_area`, the triangles larger than it (in the mesh's length units squared)
       are split, in a random order, at the midpoint of one edge (`edge="random"`, the
       leopard paper's "random new vertices", or `"longest"`, longest-edge bisection, which
       keeps the triangles' shapes better), with the triangle across that edge; the new
       vertex takes the mean of its two parents' values. With mass="barycentric" division
       conserves the mass-weighted total exactly;
    4. the operator is rebuilt (outside compiled code) and the run goes on.

    The vertex capacity is the state's (`State.from_arrays(..., capacity=(vertices,))`,
    `Initial(capacity=...)`, `Phase(capacity=...)`): a division beyond it is not made and the
    run's status records an overflow (`simulate` raises, as a growing lattice's does). The
    time step is checked against the rebuilt operator's limit at every event.

    Args:
        rate: relative growth rate of lengths per unit time (>= 0; an array leaf, concrete
            when the run starts).
        field: None, or a growth factor >= 0 per vertex of the initial mesh.
        divide_area: None (no division) or the area above which a triangle divides (> 0).
        every: steps between growth events (>= 1).
        dilute: dilute the concentrations as the vertices' areas grow.
        edge: which edge of a dividing triangle is split: "random" or "longest".
        seed: the seed of the divisions' random choices: the mesh after n steps depends on
            the initial mesh, this growth and n only (`grown`), never on the fields.
    """

    rate: Array
    field: Array | None
    divide_area: float | None = eqx.field(static=True)
    every: int = eqx.field(static=True)
    dilute: bool = eqx.field(static=True)
    edge: str = eqx.field(static=True)
    seed: int = eqx.field(static=True)

    def __init__(self, rate=0.0, *, field=None, divide_area=None, every: int = 50, dilute: bool = False,
                 edge: str = "random", seed: int = 0):
        self.rate = as_float_array(rate, "MeshGrowth.rate")
        if field is None:
            self.field = None
        else:
            self.field = as_float_array(field, "MeshGrowth.field")
            if self.field.ndim != 1:
                raise ValueError(f"MeshGrowth.field must hold one factor per vertex, shape (vertices,) "
                                 f"(got {self.field.shape})")
            check_finite(self.field, "MeshGrowth.field")
            check_range(self.field, "MeshGrowth.field (growth factor per vertex)", low=0.0)
        if divide_area is not None:
            try:
                divide_area = float(divide_area)
            except (TypeError, ValueError) as err:
                raise ValueError(f"MeshGrowth.divide_area must be None or an area > 0 (got {divide_area!r})") from err
            if not (divide_area > 0 and math.isfinite(divide_area)):
                raise ValueError(f"MeshGrowth.divide_area (an area) must lie in (0, +inf) (got {divide_area})")
        self.divide_area = divide_area
        if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
            raise ValueError(f"MeshGrowth.every (steps between growth events) must be an integer >= 1 (got {every!r})")
        self.every = int(every)
        self.dilute = bool(dilute)
        check_choice(edge, "MeshGrowth.edge", EDGES)
        self.edge = edge
        if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
            raise ValueError(f"MeshGrowth.seed must be an integer >= 0 (got {seed!r})")
        self.seed = int(seed)

    def __check_init__(self):
        check_finite(self.rate, "MeshGrowth.rate")
        check_range(self.rate, "MeshGrowth.rate (relative growth of lengths per unit time)", low=0.0)

    # ---- the schedule and the geometry ---------------------------------------------------
    def events(self, steps: int, done: int = 0) -> int:
        """Growth events in phase steps done + 1 .. done + steps."""
        return (int(done) + int(steps)) // self.every - int(done) // self.every

    def geometry(self, mesh, capacity: int, steps: int, dt):
        """The `MeshGeometry` after `steps` phase steps from `mesh` (its events replayed)."""
        if not isinstance(mesh, Mesh):
            raise ValueError(f"MeshGrowth grows a mesh: domain must be mj.Mesh(...) (got {type(mesh).__name__})")
        if mesh.directional is not None:
            raise ValueError("MeshGrowth: an anisotropic mesh (direction=) cannot grow: its direction field is not "
                             "defined on new vertices")
        if mesh.operator != "cotangent":  # the geometry rebuilds the cotangent operator at each event
            raise ValueError(f"MeshGrowth grows meshes with the cotangent operator (got operator={mesh.operator!r}): "
                             "its rebuilt operator would silently change the model")
        if capacity < mesh.n_vertices:
            raise ValueError(f"MeshGrowth: the vertex capacity {capacity} is below the mesh's {mesh.n_vertices} "
                             "vertices")
        if self.field is not None and self.field.shape[0] != mesh.n_vertices:
            raise ValueError(f"MeshGrowth.field has {self.field.shape[0]} factors; the mesh has {mesh.n_vertices} "
                             "vertices")
        if not is_concrete(self.rate, dt):
            raise ValueError("MeshGrowth runs eagerly (its geometry is built in NumPy between compiled chunks): "
                             "its rate and dt must be concrete, not traced by jit, vmap or grad")
        geometry = MeshGeometry(mesh, capacity, None if self.field is None else np.asarray(self.field))
        for _ in range(self.events(steps)):
            geometry.event(self, float(dt))
        return geometry

    def grown(self, mesh, steps: int, dt, capacity: int | None = None):
        """The mesh after `steps` steps of a phase with this growth from `mesh`, as a `Mesh`
        (the run's own mesh: the same events, replayed). `capacity`: the run's vertex
        capacity (default: unlimited), which stops the divisions where the run's stopped."""
        cap = np.iinfo(np.int32).max if capacity is None else int(capacity)
        return self.geometry(mesh, cap, steps, dt).mesh()


def _refuse(options, save_every):
    if save_every is not None:
        raise ValueError("rollout takes snapshots of one shape; a growing mesh changes its vertices: use simulate "
                         "in pieces (each piece's mesh is MeshGrowth.grown)")
    for name in ("sources", "until", "plan"):
        if options[name] is not None and not (name == "sources" and not tuple(options[name])):
            raise ValueError(f"{name}= is not supported with MeshGrowth")
    if options["stencil"] is not None:
        raise ValueError("MeshGrowth grows a mesh: pass domain=mj.Mesh(...), not a lattice stencil")
    solver = options["solver"]
    if solver is not None and type(solver).__name__ != "Euler":
        raise ValueError(f"MeshGrowth steps with forward Euler (the default solver), not {type(solver).__name__}")


def run_growing_mesh(model, state, steps, dt, boundary, options, save_every=None, description=None, *,
                     check_inputs):
    """`simulate`'s run for `growth=MeshGrowth(...)`: (final State, RunStatus, None).
    `check_inputs` is `simulate`'s own check of a run's inputs (passed down, so this module
    does not import the entry points that call it)."""
    growth, mesh = options["growth"], options["domain"]
    _refuse(options, save_every)
    if boundary is not None:
        raise ValueError("MeshGrowth grows a mesh: pass domain=mj.Mesh(...), not a lattice boundary")
    if not isinstance(state, State) or state.ndim != 1:
        raise ValueError("MeshGrowth needs a State with one value per vertex and a vertex capacity, "
                         "State.from_arrays([...], capacity=(vertices,))")
    if not is_concrete(state.fields, state.step, dt):
        raise ValueError("MeshGrowth runs eagerly (its geometry is built in NumPy between compiled chunks): "
                         "not under jax.jit, vmap or grad")
    origin = options["origin"]
    done = steps_done(state, origin)
    geometry = _resumed_geometry(mesh, growth, state.capacity[0], float(dt), done)
    if geometry.n_vertices != state.shape[0]:
        raise ValueError(f"MeshGrowth: the state has {state.shape[0]} active vertices but the mesh grown for {done} "
                         f"phase steps has {geometry.n_vertices}; pass the state this phase's run made (and its "
                         "origin=), or the mesh it started from")
    cfg = Config(bounds=bounds_policy(options["bounds"]), dynamic=True)
    domain, rho = geometry.stepping_domain(rho=STATED_RHO, measure=options["check_dt"])
    slots = domain.neighbours.shape[0]
    euler = as_solver(None)  # forward Euler
    check_inputs(model, domain, state, steps, dt, cfg, None, False, euler)
    max_d = float(model.max_diffusion())

    def check(rho, when):
        if options["check_dt"] and max_d > 0 and float(dt) * max_d * rho > 2.0:
            raise ValueError(f"MeshGrowth: {when}, dt = {float(dt):g} is beyond the explicit-Euler limit of the "
                             f"mesh's operator (spectral radius {rho:.6g}, largest rate {max_d:g}): the largest "
                             f"stable dt is {2.0 / (rho * max_d):.6g}. Use a smaller dt, a larger divide_area or "
                             "edge='longest' (divisions make smaller triangles), or check_dt=False")

    check(rho, f"at the run's start ({geometry.n_vertices} vertices)")
    dt_arr = as_float_array(dt, "dt").astype(state.fields.dtype)
    origin_arr = jnp.asarray(state.step if origin is None else origin, jnp.int32)
    label = description if description is not None else (
        options["progress"] if isinstance(options["progress"], str) else type(model).__name__)
    bar = progress_bar(steps, label) if options["progress"] and steps else None
    status, current, t = RunStatus.healthy(), state, 0
    try:
        while t < steps:
            n = min(steps - t, growth.every - (done + t) % growth.every)
            current, piece, _ = drive(model, domain, current, n, dt_arr, cfg, None, (), options["key"], origin_arr,
                                      options["checkpoint"], False, None, None, "", WholeCapacity(), euler, None)
            status = status.merge(piece)
            t += n
            if bar is not None:
                bar.update(n)
            if int(status.nonfinite_step) >= 0:
                break
            if (done + t) % growth.every == 0:  # a growth event: outside compiled code
                fields = geometry.event(growth, float(dt), np.asarray(current.fields, np.float64))
                current = State(jnp.asarray(fields, current.fields.dtype), (geometry.n_vertices,), current.step,
                                current.time, current.names, growable=True)
                domain, rho = geometry.stepping_domain(slots, STATED_RHO, options["check_dt"])
                slots = domain.neighbours.shape[0]
                check(rho, f"after the growth event at phase step {done + t} ({geometry.n_vertices} vertices)")
                if geometry.overflow:
                    status = status.merge(RunStatus(-1, True))
    finally:
        if bar is not None:
            bar.close()
    _LAST[:] = [(mesh, growth, state.capacity[0], float(dt), done + t, copy.deepcopy(geometry))]
    return current, status, None


# The geometry where the last run ended: a run cut into pieces (an experiment's frames and
# checkpoints) continues from it instead of replaying its events from the phase's start.
# Kept only for the same mesh and growth objects, capacity, dt and step: then it is the
# replay's result, since the geometry depends on those alone.
_LAST: list = []


def _resumed_geometry(mesh, growth, capacity: int, dt: float, done: int):
    """The geometry after `done` phase steps: the last run's, when it ended there, or replayed."""
    if _LAST:
        m, g, cap, d, step, geometry = _LAST[0]
        if m is mesh and g is growth and (cap, d, step) == (capacity, dt, done):
            return copy.deepcopy(geometry)
    return growth.geometry(mesh, capacity, done, dt)
