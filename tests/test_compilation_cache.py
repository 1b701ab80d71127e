"""The persistent compilation cache: where it lives, when it is off, that programs reach it."""

import subprocess
import sys

import jax
import jax.numpy as jnp
import pytest

import morphojax as mj
from morphojax import _compilation_cache as cc


@pytest.fixture
def restore_cache_config():
    saved = {k: jax.config.values[k] for k in ("jax_compilation_cache_dir",
                                               "jax_persistent_cache_min_compile_time_secs")}
    yield
    for k, v in saved.items():
        jax.config.update(k, v)


def test_default_folder_follows_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv(cc.ENVIRONMENT, str(tmp_path / "here"))
    assert cc.default_cache_dir() == tmp_path / "here"
    for off in ("off", "0", "", "None"):
        monkeypatch.setenv(cc.ENVIRONMENT, off)
        assert cc.default_cache_dir() is None
        assert mj.use_compilation_cache() is None
    monkeypatch.delenv(cc.ENVIRONMENT)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cc.default_cache_dir() == tmp_path / "xdg" / "morphojax" / "jax"


def test_a_folder_that_cannot_be_made_warns_and_leaves_jax_as_it_was(tmp_path, restore_cache_config):
    before = jax.config.values["jax_compilation_cache_dir"]
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    with pytest.warns(UserWarning, match="compilation cache is off"):
        assert mj.use_compilation_cache(blocker / "jax") is None
    assert jax.config.values["jax_compilation_cache_dir"] == before
    with pytest.raises(ValueError, match="min_compile_seconds"):
        mj.use_compilation_cache(tmp_path, min_compile_seconds=-1)


def test_compiled_programs_are_written_and_loaded_by_a_new_process(tmp_path):
    # a new process: JAX reads the cache folder once, when it first compiles
    script = ("import sys, jax, jax.numpy as jnp, morphojax as mj\n"
              "mj.use_compilation_cache(sys.argv[1], min_compile_seconds=0)\n"
              "f = jax.jit(lambda x: jnp.cumsum(jnp.sin(x) * 3.0))\n"
              "print(float(f(jnp.arange(7.0))[-1]))\n")
    folder = tmp_path / "jax"
    first = subprocess.run([sys.executable, "-c", script, str(folder)], capture_output=True, text=True, check=True)
    entries = sorted(p.name for p in folder.iterdir())
    assert any("cumsum" in name or "lambda" in name for name in entries), entries
    second = subprocess.run([sys.executable, "-c", script, str(folder)], capture_output=True, text=True, check=True)
    assert first.stdout == second.stdout  # the same result from the loaded program
    assert sorted(p.name for p in folder.iterdir()) == entries  # loaded, not written again
    expected = float(jnp.cumsum(jnp.sin(jnp.arange(7.0)) * 3.0)[-1])
    assert float(first.stdout) == pytest.approx(expected, rel=1e-6)


def test_the_command_line_can_turn_it_off():
    from morphojax.cli import build_parser

    args = build_parser().parse_args(["--no-compilation-cache", "presets"])
    assert args.no_compilation_cache
    assert not build_parser().parse_args(["presets"]).no_compilation_cache
