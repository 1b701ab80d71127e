"""fitting/: targets, statistics, parameter spaces, gradients, an end-to-end fit, the CLI."""

import json

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from PIL import Image

import fitting
import morphojax as mj
from fitting._stats import StatsConfig

# ---- targets ---------------------------------------------------------------------------


def _stripes(width=240, height=180, period=40.0, angle=0.3):
    yy, xx = np.mgrid[0:height, 0:width]
    return 0.5 + 0.5 * np.sin(2 * np.pi * (xx * np.cos(angle) + yy * np.sin(angle)) / period)


def test_load_target_modes_crop_and_resolution(tmp_path):
    img = (_stripes() * 255).astype(np.uint8)
    rgb = np.stack([img, img // 2, 255 - img], -1)
    Image.fromarray(rgb, "RGB").save(tmp_path / "rgb.png")
    Image.fromarray(img, "L").save(tmp_path / "grey.png")
    rgba = np.dstack([rgb, img])
    Image.fromarray(rgba, "RGBA").save(tmp_path / "rgba.png")
    t = fitting.load_target(tmp_path / "rgb.png", cell_pixels=5.0)
    assert t.field.shape == (36, 48) and 0 <= t.field.min() and t.field.max() <= 1
    g = fitting.load_target(tmp_path / "grey.png", crop=(10, 20, 210, 170), cell_pixels=4.0)
    assert g.field.shape == (38, 50) and g.crop == (10, 20, 210, 170)
    a = fitting.load_target(tmp_path / "rgba.png", channel="alpha", cell_pixels=5.0)
    b = fitting.load_target(tmp_path / "rgba.png", channel="blue", invert=True, cell_pixels=5.0)
    np.testing.assert_allclose(a.field, b.field, atol=0.02)  # blue = 255 - alpha, inverted
    # the resolution estimated from the dominant wavelength: 40 px / 8 cells = 5 px per cell
    est = fitting.load_target(tmp_path / "grey.png")
    assert est.cell_pixels == pytest.approx(5.0, rel=0.1)


def test_exif_orientation_is_honoured(tmp_path):
    img = np.zeros((60, 100), np.uint8)
    img[:, :50] = 255  # left half white
    exif = Image.Exif()
    exif[0x0112] = 6  # rotate 90 degrees clockwise when displayed
    Image.fromarray(img, "L").save(tmp_path / "rot.jpg", exif=exif.tobytes())
    t = fitting.load_target(tmp_path / "rot.jpg", cell_pixels=1.0)
    assert t.pixels.shape == (100, 60)  # displayed upright: taller than wide
    assert t.pixels[:45].mean() > 0.9 and t.pixels[55:].mean() < 0.1  # the white half is now on top


def test_target_errors(tmp_path):
    Image.fromarray((_stripes() * 255).astype(np.uint8), "L").save(tmp_path / "ok.png")
    (tmp_path / "bad.png").write_bytes(b"not an image")
    with pytest.raises(ValueError, match="cannot read image .*bad.png"):
        fitting.load_target(tmp_path / "bad.png")
    with pytest.raises(ValueError, match="no such file"):
        fitting.load_target(tmp_path / "missing.png")
    with pytest.raises(ValueError, match=r"crop \(0, 0, 500, 100\) lies outside the image of 240x180"):
        fitting.load_target(tmp_path / "ok.png", crop=(0, 0, 500, 100))
    with pytest.raises(ValueError, match="image too small to measure"):
        fitting.load_target(tmp_path / "ok.png", crop=(0, 0, 10, 10))
    with pytest.raises(ValueError, match="image too small to measure.*lattice"):
        fitting.load_target(tmp_path / "ok.png", cell_pixels=20.0)
    with pytest.raises(ValueError, match="unknown channel 'purple'"):
        fitting.load_target(tmp_path / "ok.png", channel="purple")
    with pytest.raises(ValueError, match="no contrast"):
        fitting.load_target(np.ones((40, 40)))


# ---- statistics ------------------------------------------------------------------------


def test_wavelength_and_size_independence():
    for period in (8.0, 16.0):  # whole periods on 64 cells (no spectral leakage)
        x = jnp.asarray(_stripes(64, 64, period * 1.0, angle=0.0), jnp.float32)
        assert float(fitting.texture_stats(x)["wavelength"]) == pytest.approx(period, rel=0.05)
    state = mj.simulate(mj.Turing(20.0, 1.5, lower=(0, 3.5)), mj.paper_state(jax.random.key(0), (128, 128)),
                        steps=4000, dt=0.008)
    big = state.arrays()[1]
    s_big = fitting.texture_stats(jnp.asarray(big))
    s_small = fitting.texture_stats(jnp.asarray(big[:64, :64]))
    assert float(s_small["wavelength"]) == pytest.approx(float(s_big["wavelength"]), rel=0.1)
    assert float(s_small["dark"]) == pytest.approx(float(s_big["dark"]), abs=0.05)


def test_statistics_are_differentiable():
    x = jnp.asarray(np.random.default_rng(0).uniform(size=(32, 32)), jnp.float32)
    t = fitting.texture_stats(x + 0.1 * jnp.sin(jnp.arange(32) / 3.0))
    cfg = StatsConfig(orientation=True)
    g = jax.grad(lambda f: fitting.distance(fitting.texture_stats(f, cfg), fitting.texture_stats(x, cfg), cfg))(
        x * 0.9 + 0.05)
    assert np.isfinite(np.asarray(g)).all() and float(jnp.abs(g).sum()) > 0
    assert t["quantiles"].shape == (10,)


# ---- parameter spaces ------------------------------------------------------------------


def test_param_space_bounds_and_ordering():
    space = fitting.ParamSpace.build(["ratio", "scale", "lower_b", "upper_b"], bounds={"lower_b": (0.0, 5.0)})
    z = jnp.asarray(np.random.default_rng(1).normal(scale=4.0, size=(500, 4)), jnp.float32)
    vals = np.asarray(space.from_free(z))
    assert (vals[:, 0] >= 2.0).all() and (vals[:, 0] <= 50.0).all()
    assert (vals[:, 1] > 0).all() and (vals[:, 2] <= vals[:, 3]).all()
    back = np.asarray(space.from_free(jnp.asarray(space.to_free(vals[:20]), jnp.float32)))
    np.testing.assert_allclose(back, vals[:20], rtol=2e-3)
    with pytest.raises(ValueError, match="no default bounds for parameter 'colour'"):
        fitting.ParamSpace.build(["colour"])
    with pytest.raises(ValueError, match="low < high"):
        fitting.ParamSpace.build(["ratio"], bounds={"ratio": (5.0, 1.0)})


# ---- gradients on short horizons ----------------------------------------------------------


def test_short_horizon_gradients_match_finite_differences():
    """Through a short run (every step differentiated) the fit's loss gradient matches
    central differences in float64; long horizons are what the truncated window is for."""
    with jax.enable_x64(True):
        sim = fitting.Simulator(mj.Turing(), shape=(24, 24), steps=150, window=150)
        target = fitting.texture_stats(jnp.asarray(sim.run({"ratio": 10.0, "scale": 1.0}, jax.random.key(5))))
        keys = jax.random.split(jax.random.key(1), 2)

        def loss(theta):
            fields = jax.vmap(lambda k: sim.run({"ratio": theta[0], "scale": theta[1]}, k))(keys)
            return fitting.distance(fitting.mean_stats(fields), target)

        theta = jnp.array([14.0, 1.3])
        g = np.asarray(jax.grad(loss)(theta))
        for i in range(2):
            h = np.zeros(2)
            h[i] = 1e-5 * float(theta[i])
            fd = (float(loss(theta + h)) - float(loss(theta - h))) / (2 * h[i])
            assert g[i] == pytest.approx(fd, rel=1e-3, abs=1e-6)


# ---- end to end -------------------------------------------------------------------------


@pytest.fixture(scope="module")
def small_fit():
    sim = fitting.Simulator(mj.Turing(), shape=(32, 32), steps=3000, window=300)
    truth = {"ratio": 20.0, "scale": 1.2}
    field = np.asarray(sim.run(truth, jax.random.key(77)))
    result = fitting.fit(field, model="turing", fit=["ratio", "scale"], shape=(32, 32), steps=3000, window=300,
                         seeds=2, n_design=12, rounds=1, keep=1, max_steps=6, batch_size=8, bounds={
                             "ratio": (4.0, 40.0), "scale": (0.5, 3.0)})
    return truth, field, result


def test_fit_recovers_a_synthetic_target(small_fit):
    truth, _, result = small_fit
    assert result.params["scale"] == pytest.approx(truth["scale"], rel=0.15)
    assert result.loss <= 2.0 * result.noise_floor
    assert set(result.timings) >= {"design", "noise", "local", "report", "total"}
    assert result.history and result.history[0]["stage"] == "design"
    data = result.to_json()
    assert set(data["params"]) == {"ratio", "scale"}
    json.dumps(data, allow_nan=False)  # strict JSON


def test_preview(small_fit, tmp_path):
    _, _, result = small_fit
    img = result.preview(tmp_path / "p.png")
    assert img.width > 3 * 200 and (tmp_path / "p.png").exists()


def test_gradient_descent_loop_decreases_the_loss():
    z, losses = fitting.gradient_descent(lambda z: jnp.sum((z - 3.0) ** 2), jnp.zeros(2), learning_rate=0.5,
                                         steps=8)
    assert losses[-1] < losses[0] and np.allclose(np.asarray(z), 3.0, atol=0.5)


def _growing_experiment():
    from morphojax._experiment import Experiment, Initial, Phase

    return Experiment(
        name="grow", initial=Initial("paper", (16, 16)),
        phases=(Phase(mj.Turing(20.0, 1.0), steps=200, dt=0.01, name="static"),
                Phase(mj.Turing(8.0, 1.0), steps=300, dt=0.01, growth=mj.Growth(1.0), name="growth",
                      capacity=(20, 20))),
    )


def test_simulator_with_a_growing_experiment():
    exp = _growing_experiment()
    sim = fitting.Simulator(exp, window=100)
    assert sim.final_shape() == (19, 19)
    sim.check_names(["ratio", "growth:ratio", "growth_rate"])
    with pytest.raises(ValueError, match="cannot fit 'colour'"):
        sim.check_names(["colour"])
    field = sim.run({"growth:ratio": 9.0}, jax.random.key(0))
    assert field.shape == (19, 19) and np.isfinite(np.asarray(field)).all()
    g = jax.grad(lambda r: jnp.mean(sim.run({"ratio": r}, jax.random.key(0)) ** 2))(8.0)
    assert np.isfinite(float(g)) and float(g) != 0.0


def test_fit_a_growing_experiment():
    """`fit` with a multi-phase experiment: a parameter of one phase, growth rates checked."""
    exp = _growing_experiment()
    target = np.asarray(fitting.Simulator(exp, window=100).run({"growth:ratio": 9.0}, jax.random.key(42)))
    with pytest.raises(ValueError, match="beyond its capacity 20x20"):
        fitting.fit(target, model=exp, fit=["growth_rate"], bounds={"growth_rate": (0.5, 3.0)})
    res = fitting.fit(target, model=exp, fit=["growth:ratio"], bounds={"growth:ratio": (4.0, 20.0)}, seeds=2,
                      n_design=6, rounds=0, keep=1, method="nelder-mead", max_steps=4, window=100, noise_seeds=2)
    assert 5.0 < res.params["growth:ratio"] < 16.0 and np.isfinite(res.loss)
    assert np.asarray(res.fields["fit"]).shape == (19, 19)
    assert isinstance(res.model, mj.Experiment) and res.to_json()["params"] == res.params


def test_cli_fit(tmp_path, small_fit):
    from morphojax.cli import main

    # the same simulator settings as `small_fit`, so the compiled programs are reused
    sim = fitting.Simulator(mj.Turing(), shape=(40, 40), steps=3000, window=300)
    field = np.asarray(sim.run({"ratio": 15.0, "scale": 1.0}, jax.random.key(3)))
    z = (field - field.min()) / (np.ptp(field) + 1e-9)
    Image.fromarray((z * 255).astype(np.uint8), "L").resize((160, 160), Image.NEAREST).save(tmp_path / "t.png")
    code = main(["fit", str(tmp_path / "t.png"), "--model", "turing", "--fit", "ratio,scale", "--cell-pixels", "4",
                 "--shape", "32", "32", "--steps", "3000", "--window", "300", "--seeds", "2", "--design", "6",
                 "--rounds", "0", "--keep", "1", "--max-steps", "6", "--bounds", "ratio=4:40", "--bounds", "scale=0.5:3", "--no-binarise",
                 "--json", str(tmp_path / "out.json"),
                 "--preview", str(tmp_path / "out.png"), "--no-progress"])
    assert code == 0
    data = json.loads((tmp_path / "out.json").read_text())
    assert set(data["params"]) == {"ratio", "scale"} and data["target"]["cell_pixels"] == 4.0
    assert (tmp_path / "out.png").exists()
    assert main(["fit", str(tmp_path / "t.png"), "--crop", "0,0,999,10", "--json", str(tmp_path / "x.json")]) == 2
