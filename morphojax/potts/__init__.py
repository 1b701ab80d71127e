"""The cellular Potts model (Tinson 2022, section III.B): cells as sets of lattice sites.

    import morphojax as mj
    model = mj.Potts.paper003(j_like=3.0)               # T 10, V 25, lambda 2, order 2
    state = mj.potts_blob((100, 100), 40, 5, key=jax.random.key(0))
    final, energy = model.run(state, 3000, jax.random.key(1), energy=True)

Where each job lives (private modules, re-exported here and by `morphojax`):

- `_state`: `PottsState` (ids, types, volumes) and `potts_blob`, the paper's initial disc;
- `_model`: `Potts`, its Hamiltonian (`energy`) and `run`;
- `_sweep`: the compiled loop, copy attempts in parallel on four sub-lattices;
- `_observables`: same-type clusters, the descriptor of spots and stripes;
- `_pictures`: types coloured, cell borders drawn.
"""

from ._model import Potts
from ._observables import type_clusters
from ._pictures import TYPE_COLOURS, potts_image
from ._state import PottsState, potts_blob

__all__ = ["Potts", "PottsState", "TYPE_COLOURS", "potts_blob", "potts_image", "type_clusters"]
