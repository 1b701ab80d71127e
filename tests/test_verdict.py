"""fitting/_verdict.py: the held-out texture distance, its yardsticks, degenerate coats, and
the verdict a fit carries (JSON, CLI, describe, log lines)."""

import json

import jax
import numpy as np
import pytest

import fitting
import morphojax as mj
from fitting import _fit as fit_module
from fitting import _verdict as verdict


def band_texture(shape, wavelength, seed, angle=None, spread=0.08):
    """An independent texture generator: white noise band-passed around |k| = 1/wavelength
    (and, with `angle`, around one direction), thresholded at its median: spots and
    labyrinths of a known scale, and stripes."""
    rng = np.random.default_rng(seed)
    ky = np.fft.fftfreq(shape[0])[:, None]
    kx = np.fft.fftfreq(shape[1])[None, :]
    radius = np.hypot(kx, ky)
    gain = np.exp(-0.5 * ((radius - 1.0 / wavelength) / (spread / wavelength)) ** 2)
    if angle is not None:  # stripes along `angle`: their wave vector is across it
        across = np.abs(-np.sin(angle) * kx + np.cos(angle) * ky) / np.maximum(radius, 1e-12)
        gain = gain * np.exp(-0.5 * ((1.0 - across) / 0.02) ** 2)
    field = np.real(np.fft.ifft2(np.fft.fft2(rng.normal(size=shape)) * gain))
    return (field > np.median(field)).astype(float)


def test_wavelength_of_band_textures():
    for lam in (6.0, 9.0, 14.0):
        found = verdict.wavelength_of(band_texture((96, 96), lam, 1))
        assert found == pytest.approx(lam, rel=0.1), (lam, found)
    assert np.isnan(verdict.wavelength_of(np.ones((20, 20))))


def test_distance_separates_the_same_texture_from_others_and_from_noise():
    target = band_texture((64, 128), 9.0, 0)
    same = [band_texture((64, 64), 9.0, s) for s in (1, 2, 3)]
    coarse = [band_texture((64, 64), 18.0, s) for s in (1, 2)]
    stripes = [band_texture((64, 64), 9.0, s, angle=0.6) for s in (1, 2)]
    train, heldout, apart = verdict.split_target(target)
    assert apart and train.shape == heldout.shape == (64, 64)
    good = verdict.judge(same, target, heldout, apart)
    assert good["convincing"] and good["distance"] <= 2 * good["floor"] and good["distance"] < 0.3 * good["noise"]
    assert good["target_wavelength"] == pytest.approx(9.0, rel=0.1)
    for other in (coarse, stripes):
        report = verdict.judge(other, target, heldout, apart)
        assert not report["convincing"] and report["distance"] > 2 * good["distance"]
    # white noise with the target's values is as far as the noise yardstick says
    noise = [np.random.default_rng(s).permutation(heldout.ravel()).reshape(heldout.shape) for s in (5, 6)]
    report = verdict.judge(noise, target, heldout, apart)
    assert not report["convincing"] and report["distance"] == pytest.approx(report["noise"], rel=0.2)
    # symmetric, zero on itself, every group in [0, 1]
    a, b = same[0], coarse[0]
    assert verdict.texture_distance(a, b, 9.0) == pytest.approx(verdict.texture_distance(b, a, 9.0))
    assert verdict.texture_distance(a, a, 9.0) == 0.0
    groups = verdict.group_distances(verdict.features(a, 9.0), verdict.features(noise[0], 9.0))
    assert set(groups) == set(verdict.GROUPS) and all(0.0 <= v <= 1.0 for v in groups.values())


def test_a_small_target_is_judged_on_its_halves_and_says_so():
    target = band_texture((40, 48), 9.0, 0)  # halves of 40x24 hold under 4 wavelengths
    train, heldout, apart = verdict.split_target(target)
    assert not apart and train is heldout
    report = verdict.judge([band_texture((40, 40), 9.0, 1)], target, heldout, apart)
    assert report["held_out"] is False
    assert "too small to hold a tile out" in verdict.verdict_text("turing", report, None, auto=True)


def test_degenerate_coats_are_named():
    assert verdict.degenerate([band_texture((48, 48), 9.0, 1)], 9.0) is None
    assert "grid-scale" in verdict.degenerate([band_texture((48, 48), 2.5, 1, spread=0.02)], 9.0)
    assert "against the target's 9.0" in verdict.degenerate([band_texture((48, 48), 16.0, 1)], 9.0)
    assert verdict.degenerate([np.full((16, 16), 0.3)], 9.0).startswith("uniform")
    assert verdict.degenerate([np.full((16, 16), np.nan)], 9.0).startswith("unstable")


def test_off_scale_is_grid_scale_or_twenty_percent_off():
    lams = np.array([2.5, 3.9, 7.0, 7.3, 10.7, 11.1, np.nan])
    np.testing.assert_array_equal(verdict.off_scale(lams, 9.0), [True, True, True, False, False, True, True])
    assert not verdict.off_scale(12.0, np.nan) and verdict.off_scale(3.0, np.nan)  # no target: grid scale only


def test_verdict_text():
    report = {"distance": 0.5, "floor": 0.1, "noise": 0.55, "held_out": True, "convincing": False}
    text = verdict.verdict_text("leopard", report, "wavelength 2.1 cells: grid-scale", auto=True)
    assert text.startswith("no family reproduces this photo; the nearest is leopard")
    assert "grid-scale" in text and "5.0x the within-target floor" in text
    good = {**report, "distance": 0.15, "convincing": True}
    assert verdict.verdict_text("turing", good, None, auto=False).startswith("convincing: turing reproduces")
    # a rejected coat is never convincing, whatever its distance
    assert verdict.verdict_text("turing", good, "uniform: no pattern forms", auto=False).startswith("no fit of family")


def test_correlated_pairs_from_a_known_jacobian():
    from fitting._uncertainty import correlated_pairs

    rng = np.random.default_rng(0)
    a = rng.normal(size=30)
    J = np.stack([a, a + 0.05 * rng.normal(size=30), rng.normal(size=30)], axis=1)  # 0 and 1 trade off
    assert correlated_pairs(J, np.ones(30), ["ratio", "upper_a", "scale"], np.zeros(3, bool)) == [
        ["ratio", "upper_a"]]
    assert correlated_pairs(J, np.ones(30), ["ratio", "upper_a", "scale"], np.array([False, True, False])) == []


def test_a_fit_that_can_only_reach_grid_scale_is_rejected_and_logged(capsys):
    """Bounds that allow only grid-scale Turing patterns (scale 0.1-0.2 gives wavelengths of
    about 3 cells against the target's 8): the fit returns its nearest point, rejected and not
    convincing, and says so; with stderr not a terminal, progress is one log line per stage."""
    sim = fitting.Simulator(mj.Turing(), shape=(32, 32), steps=3000, window=300)
    field = np.asarray(sim.run({"ratio": 20.0, "scale": 1.2}, jax.random.key(77)))
    res = fitting.fit(field, model="turing", fit=["ratio", "scale"], shape=(32, 32), steps=3000, window=300,
                      seeds=2, n_design=8, rounds=0, keep=1, max_steps=0, noise_seeds=3, intervals=False,
                      bounds={"ratio": (4.0, 40.0), "scale": (0.1, 0.2)})
    assert res.rejected is not None and "grid-scale" in res.rejected and not res.convincing
    assert res.verdict.startswith("no fit of family turing reproduces this photo")
    assert res.describe().startswith(res.verdict)
    data = json.loads(json.dumps(res.to_json(), allow_nan=False))
    assert data["convincing"] is False and set(data["heldout"]) >= {"distance", "floor", "noise", "held_out"}
    assert data["rejected"] == res.rejected and data["correlated"] == []
    assert res.timings["total"] >= res.timings["fit"] > 0 and "verdict" in res.timings
    log = capsys.readouterr().err
    assert "fit turing: design done" in log and "best loss" in log and "fit turing: finished in" in log


def test_the_training_half_aims_at_the_whole_targets_wavelength(monkeypatch):
    """A split target's training fit aims at the wavelength the verdict judges by (the
    whole's), not its half's: two halves of different scales make the difference plain. The
    fit's own `target_stats` is watched, so a stage that dropped the wavelength would show."""
    whole = np.concatenate([band_texture((72, 72), 7.0, 0), band_texture((72, 72), 11.0, 1)], axis=1)
    seen = {}
    real = fit_module.target_stats

    def watched(field, stats, wavelength=None):
        seen["field"], seen["stats"] = field, real(field, stats, wavelength)
        raise RuntimeError("stop after the target's statistics")

    monkeypatch.setattr(fit_module, "target_stats", watched)
    with pytest.raises(RuntimeError, match="stop after the target's statistics"):
        fitting.fit(whole, model="turing", progress=False)
    assert seen["field"].shape == (72, 72)  # the training half
    lam_whole, lam_half = verdict.target_wavelength(whole), verdict.target_wavelength(seen["field"])
    assert abs(lam_half / lam_whole - 1) > 0.1  # the halves differ: the test can tell
    assert float(seen["stats"]["wavelength"]) == pytest.approx(lam_whole, rel=1e-6)


def test_a_photos_statistics_carry_the_cameras_error(monkeypatch, tmp_path):
    """`fitting.fit` gives a photo's target the camera's observation error
    (`PHOTO_CAMERA`) and an array's none, a user's own `camera` is kept; the residuals divide
    by sqrt(noise^2 + camera^2) per group, against a NumPy computation of the rule."""
    from PIL import Image

    texture = band_texture((96, 96), 9.0, 3)
    Image.fromarray((255 * texture).astype(np.uint8), "L").save(tmp_path / "coat.png")
    seen = []

    def watched(field, stats, wavelength=None):
        seen.append(stats.camera)
        raise RuntimeError("stop after the target's statistics")

    monkeypatch.setattr(fit_module, "target_stats", watched)
    for target, stats in ((texture, None), (tmp_path / "coat.png", None),
                          (tmp_path / "coat.png", fitting.StatsConfig(camera=()))):
        with pytest.raises(RuntimeError, match="stop after"):
            fitting.fit(target, model="turing", progress=False, stats=stats)
    assert seen == [(), fitting.PHOTO_CAMERA, ()]

    plain = fitting.StatsConfig(camera=())
    photo = fitting.StatsConfig(camera=fitting.PHOTO_CAMERA)
    a = fitting.texture_stats(jax.numpy.asarray(texture, jax.numpy.float32), plain)
    b = fitting.texture_stats(jax.numpy.asarray(band_texture((96, 96), 12.0, 4), jax.numpy.float32), plain)
    got = np.asarray(fitting.residuals(a, b, photo))
    expected = []
    for name in photo.groups():
        va, vb = (np.atleast_1d(np.asarray(s[name], np.float64)) for s in (a, b))
        if name == "wavelength":
            va, vb = np.log(va), np.log(vb)
        sd = np.hypot(photo.scale(name), dict(fitting.PHOTO_CAMERA)[name])
        expected.append((va - vb) / (sd * np.sqrt(len(va))))
    np.testing.assert_allclose(got, np.concatenate(expected), rtol=2e-4, atol=1e-5)
    # the camera's error in the denominators only shrinks the distance
    assert float(fitting.distance(a, b, photo)) < float(fitting.distance(a, b, plain))
