"""JAX's persistent compilation cache, where morphojax keeps it.

On a small CPU, compiling a run's programs can cost more than running them: a fit compiles
a dozen programs (the design batch, the seeds' runs, the gradient of the loss, the
intervals), and every new process compiles them again. JAX can keep compiled programs on
disk and load them in a later process with the same program, shapes, JAX version and
machine; results are the same, only the compilation is skipped.

The command line turns the cache on (`morphojax --no-compilation-cache ...` turns it off);
in Python, `mj.use_compilation_cache()` does, since a library should not change JAX's
global configuration on import. The folder is `$MORPHOJAX_CACHE_DIR` when set (`off`
disables it), else `$XDG_CACHE_HOME/morphojax/jax`, else `~/.cache/morphojax/jax`. It grows
with every new program; deleting it is always safe.
"""

from __future__ import annotations

import os
import warnings
from pathlib import Path

ENVIRONMENT = "MORPHOJAX_CACHE_DIR"
OFF = ("", "0", "off", "none", "false")
# Programs that compile faster than this are not written (they cost more to load than to
# compile again; the default of JAX, one second, leaves out most of a small run's programs).
MIN_COMPILE_SECONDS = 0.2


def default_cache_dir() -> Path | None:
    """The folder the cache uses: `$MORPHOJAX_CACHE_DIR` (None when it says off), else
    `$XDG_CACHE_HOME/morphojax/jax`, else `~/.cache/morphojax/jax`."""
    if ENVIRONMENT in os.environ:
        value = os.environ[ENVIRONMENT].strip()
        return None if value.lower() in OFF else Path(value).expanduser()
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "morphojax" / "jax"


def use_compilation_cache(path: str | os.PathLike | None = None, *,
                          min_compile_seconds: float = MIN_COMPILE_SECONDS) -> Path | None:
    """Keep JAX's compiled programs in `path` (default `default_cache_dir()`), so later
    processes load them instead of compiling. Returns the folder, or None when the cache is
    off (`MORPHOJAX_CACHE_DIR=off`) or the folder cannot be made, which warns and leaves
    JAX as it was: a read-only home never stops a run."""
    import jax

    if min_compile_seconds < 0:
        raise ValueError(f"min_compile_seconds must be >= 0 (got {min_compile_seconds!r})")
    folder = Path(path).expanduser() if path is not None else default_cache_dir()
    if folder is None:
        return None
    try:
        folder.mkdir(parents=True, exist_ok=True)
        if not os.access(folder, os.W_OK):
            raise PermissionError(f"{folder} is not writable")
    except OSError as err:
        warnings.warn(f"morphojax: the compilation cache is off ({err}); set {ENVIRONMENT} to a writable folder",
                      stacklevel=2)
        return None
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", float(min_compile_seconds))
    return folder
