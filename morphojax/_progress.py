"""The progress bar every long run shows: simulations, sweeps, automata and cell runs."""

from __future__ import annotations


def progress_bar(total: int, label: str, unit: str = "step"):
    """The progress bar every long run shows (tqdm.auto: a widget in notebooks): `total`
    units named `label`, gone when done."""
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=label, unit=unit, leave=False)
