"""specula.resample: the same grids as `specula resample` on the same samples (plain, with a learned prior, on a fitted
model), a Lambertian's constant recovered exactly, and bad arguments refused in one line."""
import itertools

import numpy as np
import pytest

import specula
from conftest import cli

WL = ("--wavelengths", "400:700:100")
RUNS = itertools.count()


@pytest.fixture(scope="module")
def db(tmp_path_factory):
    """Four analytic grids and a prior learned from them (cyan-gloss left out), then samples of cyan-gloss and of the
    Lambertian green-matte at random configurations."""
    path = tmp_path_factory.mktemp("resample") / "db.h5"
    for m in ("blue-paint", "gold", "green-matte", "study-ts", "cyan-gloss"):
        cli("synth-brdf", m, *WL, "-o", f"{path}:{m}")
    cli("prior", "build", path, "--exclude", "cyan-gloss", "--channels", 3, "-o", path, "--name", "p")
    cli("synth-samples", "cyan-gloss", "--geometry", "random", "-n", 40000, *WL, "-o", f"{path}:scan")
    cli("synth-samples", "green-matte", "--geometry", "random", "-n", 20000, *WL, "-o", f"{path}:matte")
    return path


def cli_grids(db, tmp_path, samples, *flags):
    """The grid (and confidence, or None) `specula resample` writes for these flags."""
    out = tmp_path / f"cli{next(RUNS)}.h5"
    cli("resample", db, samples, "-o", f"{out}:g", *flags)
    s = specula.Store(out)
    conf = s.grid("g.confidence").values[0] if "g.confidence" in s.grids else None
    return s.grid("g").values, conf


def test_plain_is_the_clis_grid_and_a_lambertians_constant(db, tmp_path):
    g, report = specula.resample(db, "matte")
    values, conf = cli_grids(db, tmp_path, "matte")
    assert conf is None and report["confidence"] is None
    np.testing.assert_array_equal(g.values, values)
    assert report["samples"] == 20000 and report["k"] == 32 and report["weights"] == "shepard"
    assert report["summary"].startswith("resampled 20000 samples of matte")
    # Any weighted mean of one constant is that constant: rho / pi per band wherever a cell has data.
    truth = specula.Store(db).grid("green-matte").values
    has = g.values[0] >= 0
    assert 0.2 < has.mean() < 1
    for b in range(g.bands):
        np.testing.assert_allclose(g.values[b][has], truth[b][has], rtol=1e-5)
    assert np.all(g.values[:, ~has] < 0)


def test_k_weights_and_max_gap_are_the_clis_flags(db, tmp_path):
    g, report = specula.resample(db, "scan", k=8, weights="mean", max_gap=4.0)
    values, _ = cli_grids(db, tmp_path, "scan", "-k", 8, "--weights", "mean", "--max-gap", 4)
    np.testing.assert_array_equal(g.values, values)
    assert report["k"] == 8 and report["weights"] == "mean"


def test_prior_fills_every_valid_cell_with_its_confidence_as_the_cli_does(db, tmp_path):
    g, report = specula.resample(db, "scan", prior=f"{db}:p", lambda_=1e-2)
    values, conf = cli_grids(db, tmp_path, "scan", "--prior", f"{db}:p", "--lambda", 0.01)
    np.testing.assert_array_equal(g.values, values)
    c = report["confidence"]
    assert c.shape == (90, 90, 180) and c.dtype == np.float32
    np.testing.assert_array_equal(c, conf)
    valid = specula.Store(db).grid("cyan-gloss").values[0] >= 0
    assert np.all(g.values[:, valid] >= 0) and np.all((c[valid] >= 0) & (c[valid] <= 1))
    assert np.all(c[~valid] == -1)
    assert report["valid_cells"] == int(valid.sum())
    assert report["confidence_reach"] in [r["reach"] for r in report["confidence_reach_auto"]["rows"]]
    assert report["log_residuals"]["samples"] > 0
    assert report["peak_rows_auto"]["rows"] == report["log_residuals"]["ring_rows"]
    assert "retro_rise" not in report
    # Without the log residuals, with a reach given (no holdout), no peak rows and the retro band's rise: the CLI's
    # flags for all four.
    g2, report2 = specula.resample(db, "scan", prior=f"{db}:p", confidence_reach=0.5, log_residuals=False,
                                   peak_rows=0, retro_rise=True)
    values2, _ = cli_grids(db, tmp_path, "scan", "--prior", f"{db}:p", "--confidence-reach", 0.5,
                           "--no-log-residuals", "--peak-rows", 0, "--retro-rise")
    np.testing.assert_array_equal(g2.values, values2)
    assert report2["confidence_reach"] == 0.5 and "log_residuals" not in report2
    assert "confidence_reach_auto" not in report2
    assert "peak_rows" not in report2 and "peak_rows_auto" not in report2
    rise = report2["retro_rise"]
    assert rise["rows"] >= 0 and len(rise["factors"]) in (0, rise["rows"])


def test_k_holdout_is_the_clis(db, tmp_path):
    g, report = specula.resample(db, "scan", prior=f"{db}:p", k="holdout")
    values, conf = cli_grids(db, tmp_path, "scan", "--prior", f"{db}:p", "-k", "holdout")
    np.testing.assert_array_equal(g.values, values)
    np.testing.assert_array_equal(report["confidence"], conf)
    rows = report["confidence_reach_auto"]["k_rows"]
    assert [r["k"] for r in rows] == [8, 16, 32, 64]
    least = min(rows, key=lambda r: r["error"])
    assert report["k"] == report["confidence_reach_auto"]["k"] == least["k"]


def test_model_is_the_clis(db, tmp_path):
    g, report = specula.resample(db, "scan", model="ggx")
    values, conf = cli_grids(db, tmp_path, "scan", "--model", "ggx")
    np.testing.assert_array_equal(g.values, values)
    np.testing.assert_array_equal(report["confidence"], conf)
    assert report["model"]["distribution"] == "ggx" and len(report["model"]["lobes"]) == 1


def test_the_grid_saves_and_reads_back(db, tmp_path):
    g, _ = specula.resample(specula.Store(db), "matte")
    with specula.Store(tmp_path / "out.h5", "a") as out:
        out.write_grid("g", g)
    np.testing.assert_array_equal(specula.Store(tmp_path / "out.h5").grid("g").values, g.values)


@pytest.mark.parametrize("kwargs, message", [
    ({"k": "many"}, "k = 'many': give a count of neighbours, 'auto' or (with a prior) 'holdout'"),
    ({"k": 0}, "k = 0: give a count of neighbours, 'auto' or (with a prior) 'holdout'"),
    ({"k": "holdout"}, "k='holdout' is chosen by a prior's holdout, only with a prior"),
    ({"k": "holdout", "prior": "x.h5:p", "confidence_reach": 0.5},
     "k='holdout' is chosen with the reach, so not with a confidence_reach given"),
    ({"prior": "x.h5:p", "model": "ggx"}, "give prior or model, not both"),
    ({"max_gap": 0.0}, "max_gap = 0 degrees: give degrees in (0, 180]"),
    ({"max_gap": 200}, "max_gap = 200 degrees: give degrees in (0, 180]"),
    ({"model": "ggx", "lobes": 3}, "lobes = 3: give 1 or 2 microfacet lobes"),
    ({"lobes": 2}, "lobes: only with a model"),
    ({"lambda_": 0.1}, "lambda_: only with a prior"),
    ({"log_residuals": False}, "log_residuals: only with a prior"),
    ({"peak_rows": 5}, "peak_rows: only with a prior"),
    ({"retro_rise": True}, "retro_rise: only with a prior"),
    ({"prior": "x.h5:p", "peak_rows": 90}, "peak_rows = 90: give a count of theta_h rows in [0, 90) or 'auto'"),
    ({"prior": "x.h5:p", "peak_rows": "all"}, "peak_rows = 'all': give a count of theta_h rows in [0, 90) or 'auto'"),
    ({"model": "ggx", "confidence_reach": 1.5}, "confidence_reach = 1.5: give a fraction of max_gap in (0, 1]"),
    ({"model": "ggx", "confidence_reach": "auto"}, "confidence_reach='auto' is chosen only with a prior"),
    ({"confidence_reach": 0.5}, "confidence_reach: only with a prior or a model"),
    ({"weights": "mean", "power": 2.0}, "power = 2: only Shepard's weights have a power"),
])
def test_bad_arguments_are_one_usage_error(db, kwargs, message):
    with pytest.raises(specula.UsageError) as e:
        specula.resample(db, "matte", **kwargs)
    assert str(e.value) == "resample: " + message


def test_missing_store_and_samples_are_named(db, tmp_path):
    with pytest.raises(specula.MissingFileError, match="nothing.h5"):
        specula.resample(tmp_path / "nothing.h5", "matte")
    with pytest.raises(specula.InputError, match="absent"):
        specula.resample(db, "absent")
