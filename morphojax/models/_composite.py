"""Several models side by side on consecutive species of one state."""

from __future__ import annotations

import equinox as eqx
import jax.numpy as jnp

from ._base import AbstractModel


class Composite(AbstractModel):
    """Several models acting side by side on consecutive species of one state.

    `Composite((Turing(...), Reinforcement(...)))` evolves species (a, b) by the Turing
    model and species c by reinforcement, as in the leopard's development phase. Species
    names are the parts' names unless `species` is given.
    """

    parts: tuple[AbstractModel, ...]
    names: tuple[str, ...] = eqx.field(static=True)

    def __init__(self, parts, species=None):
        parts = tuple(parts)
        if not parts or not all(isinstance(p, AbstractModel) for p in parts):
            raise ValueError("Composite.parts must be a non-empty sequence of models")
        self.parts = parts
        names = tuple(species) if species is not None else tuple(n for p in parts for n in p.species)
        if len(names) != sum(p.n_species for p in parts):
            raise ValueError(f"Composite.species needs {sum(p.n_species for p in parts)} names (got {len(names)})")
        if len(set(names)) != len(names):
            names = tuple(f"{n}{i}" for i, n in enumerate(names))
        self.names = names

    @property
    def species(self):  # type: ignore[override]
        return self.names

    def _split(self, x):
        out, start = [], 0
        for p in self.parts:
            out.append(x[start : start + p.n_species])
            start += p.n_species
        return out

    @staticmethod
    def _cat(arrays):
        shape = jnp.broadcast_shapes(*(a.shape[1:] for a in arrays))
        return jnp.concatenate([jnp.broadcast_to(a, a.shape[:1] + shape) for a in arrays])

    def reaction(self, x):
        return jnp.concatenate([p.reaction(xi) for p, xi in zip(self.parts, self._split(x))])

    def diffusion(self):
        return self._cat([p.diffusion() for p in self.parts])

    def at(self, x):
        parts = tuple(p.at(xi) for p, xi in zip(self.parts, self._split(x)))
        return self if all(a is b for a, b in zip(parts, self.parts)) else Composite(parts, species=self.names)

    @property
    def lower(self):  # type: ignore[override]
        return self._cat([p.lower for p in self.parts])

    @property
    def upper(self):  # type: ignore[override]
        return self._cat([p.upper for p in self.parts])

    def unclamped_state(self):
        """The parts' closed forms side by side, or None when a part has none."""
        states = [p.unclamped_state() for p in self.parts]
        return None if any(s is None for s in states) else tuple(v for s in states for v in s)

    def homogeneous_state(self, guess=None):
        """The parts' homogeneous states side by side (the parts do not react with each
        other, so each is solved alone; `guess` has one value per species of the whole)."""
        if guess is not None:
            guess = tuple(guess)
            if len(guess) != self.n_species:
                raise ValueError(f"Composite.homogeneous_state: guess needs {self.n_species} values (got {len(guess)})")
        out, start = [], 0
        for p in self.parts:
            part = None if guess is None else guess[start : start + p.n_species]
            out.extend(p.homogeneous_state(part))
            start += p.n_species
        return tuple(out)

    def parameters(self):
        return {f"{i}.{k}": v for i, p in enumerate(self.parts) for k, v in p.parameters().items()}

    def replace(self, **changes):
        per_part: dict[int, dict] = {}
        for key, value in changes.items():
            head, _, rest = key.partition(".")
            if not head.isdigit() or int(head) >= len(self.parts):
                raise ValueError(f"Composite parameters are named 'PART.NAME' (got {key!r}); see parameters()")
            per_part.setdefault(int(head), {})[rest] = value
        parts = tuple(p.replace(**per_part[i]) if i in per_part else p for i, p in enumerate(self.parts))
        return Composite(parts, species=self.names)
