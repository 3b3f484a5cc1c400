"""The BRDF half from Python: render_sphere against the CLI's PNG and a Lambertian closed form, SpcBrdf against
decoding and looking up, target_de00 encoding against the CLI and against compare_grids, and compare_grids against
`specula brdf-diff --json`."""
import json

import matplotlib.image
import numpy as np
import pytest

from conftest import cli
import specula

NM = [400, 500, 600, 700]


@pytest.fixture(scope="module")
def spgrid(tmp_path_factory):
    path = tmp_path_factory.mktemp("render") / "rp.spgrid"
    cli("synth-brdf", "red-plastic", "--wavelengths", "400:700:100", "-o", path)
    return path


def png(path):
    return np.round(matplotlib.image.imread(path)[..., :3] * 255).astype(np.uint8)


@pytest.mark.parametrize("env", [None, "default"])
def test_render_sphere_is_the_clis_picture(spgrid, tmp_path, env):
    out = tmp_path / "cli.png"
    cli("render", spgrid, "-o", out, "--size", 48, "--light", "30,60", *(["--env", env] if env else []))
    srgb, linear = specula.render_sphere(specula.read_spgrid(spgrid), light=(30, 60), env=env, size=48)
    assert srgb.shape == linear.shape == (48, 48, 3) and srgb.dtype == np.uint8 and linear.dtype == np.float32
    np.testing.assert_array_equal(srgb, png(out))


def test_render_sphere_of_a_lambertian_is_albedo_times_cosine():
    albedo, size = 0.6, 40
    grid = specula.Grid(NM, np.full((4, 90, 90, 180), albedo / np.pi, np.float32))
    srgb, linear = specula.render_sphere(grid, light=(40, 10), size=size, illuminant="E")
    t, p = np.radians(40), np.radians(10)
    light = np.array([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)])
    c = (np.arange(size) + 0.5) / size * 2 - 1
    x, y = np.meshgrid(c, -c)
    inside = x * x + y * y < 1
    n = np.stack([x, y, np.sqrt(np.maximum(0, 1 - x * x - y * y))], -1)
    expected = albedo * np.maximum(0, n @ light)
    for ch in range(3):
        np.testing.assert_allclose(linear[..., ch][inside], expected[inside], rtol=2e-3, atol=2e-3)
    assert (linear[~inside] == 0).all() and (srgb[~inside] == 24).all()


def test_spc_brdf_evaluates_what_decoding_and_lookup_give(spgrid):
    g = specula.read_spgrid(spgrid)
    data, _ = specula.spc_encode(g, k=3)
    coded, decoded = specula.SpcBrdf(data), specula.spc_decode(data)
    assert coded.k == 3 and coded.bands == 4 and coded.reference == "self"
    rng = np.random.default_rng(2)
    n = 4000
    ti, to = rng.uniform(0.05, 1.4, n), rng.uniform(0.05, 1.4, n)
    pi, po = rng.uniform(-np.pi, np.pi, n), rng.uniform(-np.pi, np.pi, n)
    wi = np.stack([np.sin(ti) * np.cos(pi), np.sin(ti) * np.sin(pi), np.cos(ti)], -1).astype(np.float32)
    wo = np.stack([np.sin(to) * np.cos(po), np.sin(to) * np.sin(po), np.cos(to)], -1).astype(np.float32)
    got = coded.evaluate(wi.reshape(40, 100, 3), wo.reshape(40, 100, 3))
    assert got.shape == (40, 100, 4) and got.dtype == np.float32
    # The same directions as standard angles (from the float32 vectors), looked up in the decoded grid.
    w64i, w64o = wi.astype(np.float64), wo.astype(np.float64)
    angles = [np.arccos(w64i[:, 2] / np.linalg.norm(w64i, axis=1)), np.arctan2(w64i[:, 1], w64i[:, 0]),
              np.arccos(w64o[:, 2] / np.linalg.norm(w64o, axis=1)), np.arctan2(w64o[:, 1], w64o[:, 0])]
    want = np.nan_to_num(specula.brdf_lookup(decoded, *angles), nan=0.0)
    same = np.all(np.isclose(got.reshape(n, 4), want, rtol=1e-4, atol=1e-6), axis=1)
    assert same.mean() > 0.995, same.mean()  # the rest: pairs within float rounding of a cell boundary
    with pytest.raises(specula.UsageError, match="directions"):
        coded.evaluate(wi[:, :2], wo[:, :2])


def test_spc_brdf_evaluates_into_out_as_numpy_does(spgrid):
    coded = specula.SpcBrdf(specula.spc_encode(specula.read_spgrid(spgrid), k=3)[0])
    rng = np.random.default_rng(3)
    wi, wo = (rng.normal(size=(6, 50, 3)).astype(np.float32) for _ in range(2))
    wi[..., 2], wo[..., 2] = np.abs(wi[..., 2]), np.abs(wo[..., 2])
    want = coded.evaluate(wi, wo)
    out = np.full((6, 50, 4), np.nan, np.float32)
    assert coded.evaluate(wi, wo, out=out) is out
    np.testing.assert_array_equal(out, want)
    out[:] = np.nan
    coded.evaluate(wi, wo, out)  # positional, as numpy's ufuncs take it
    np.testing.assert_array_equal(out, want)
    for bad, match in [(np.empty((6, 50, 4)), "dtype float64"), (np.empty((6, 50, 3), np.float32), r"shape \(6, 50, 3\)"),
                       (np.empty((6, 50, 8), np.float32)[..., ::2], "C-contiguous"), ([0.0] * 1200, "numpy array")]:
        with pytest.raises(specula.UsageError, match=match):
            coded.evaluate(wi, wo, out=bad)
    frozen = np.empty((6, 50, 4), np.float32)
    frozen.flags.writeable = False
    with pytest.raises(specula.UsageError, match="writable"):
        coded.evaluate(wi, wo, out=frozen)
    shared = np.zeros(300 * 4, np.float32)  # wi in the first 900 floats of out's 1200
    with pytest.raises(specula.UsageError, match="shares memory"):
        coded.evaluate(shared[:900].reshape(300, 3), wo.reshape(300, 3), out=shared.reshape(300, 4))


def test_target_encoding_matches_the_cli_and_compare_grids(spgrid, tmp_path):
    g = specula.read_spgrid(spgrid)
    data, report = specula.spc_encode(g, k=3, target_de00=1.0, trials=3)
    out = tmp_path / "cli.spc"
    r = cli("encode", spgrid, "--basis", "self", "-k", 3, "--target-de00", 1.0, "--trials", 3, "-o", out, "--json")
    want = json.loads(r.stdout)
    for key in ("method", "format_version", "step", "basis", "k", "input_bytes", "output_bytes", "valid_cells",
                "rms_error", "max_abs_error", "magnitude_scale"):
        assert report[key] == pytest.approx(want[key]), key
    for key, value in want["target"].items():
        assert report["target"][key] == (value if isinstance(value, str) else pytest.approx(value, abs=1e-4)), key
    # The CLI's lighting suite, run on the decoded Python coding, agrees with what the search reached.
    coded = tmp_path / "py.spc"
    specula.write_spc(coded, data)
    suite = json.loads(cli("brdf-diff", spgrid, coded, "--json").stdout)
    assert report["target"]["reached"] and suite["de00_mean"] <= 1.0
    assert suite["de00_mean"] == pytest.approx(report["target"]["reached_de00_mean"], abs=1e-3)


def test_without_k_the_target_encoding_chooses_k_as_the_cli_does(spgrid, tmp_path):
    g = specula.read_spgrid(spgrid)
    data, report = specula.spc_encode(g, target_de00=1.0, trials=3)
    out = tmp_path / "cli.spc"
    r = cli("encode", spgrid, "--basis", "self", "--target-de00", 1.0, "--trials", 3, "-o", out, "--json")
    want = json.loads(r.stdout)
    assert report["k_search"] == want["k_search"]
    assert report["k"] == want["k"] == want["k_search"]["chosen_k"]
    searched = [c for c in want["k_search"]["candidates"] if c["searched"] and c["reached"]]
    assert report["output_bytes"] == min(c["bytes"] for c in searched)


def test_compare_grids_is_brdf_diff(spgrid, tmp_path):
    g = specula.read_spgrid(spgrid)
    data, _ = specula.spc_encode(g, k=2)
    coded = tmp_path / "c.spc"
    specula.write_spc(coded, data)
    want = json.loads(cli("brdf-diff", spgrid, coded, "--env", "default", "--size", 64, "--json").stdout)
    got = specula.compare_grids(g, specula.spc_decode(coded), size=64)
    for key in ("cells", "only_a", "only_b", "rms", "max_abs", "rel_rms_cos", "de00_mean", "de00_p95", "de00_max"):
        assert got[key] == pytest.approx(want[key], rel=1e-9, abs=1e-12), key
    assert got["de00"].shape == (64, 64) and got["de00"].max() == pytest.approx(want["de00_max"], rel=1e-6)
    with pytest.raises(TypeError, match="compare_grids: grid must be a specula.Grid"):
        specula.compare_grids(g, data)


def test_encoding_records_where_the_basis_came_from(spgrid, tmp_path):
    g = specula.read_spgrid(spgrid)
    four = specula.Basis("nmf", NM, np.eye(4)[:3] + 0.1)
    with specula.Store(tmp_path / "bases.h5", mode="a") as s:
        s.write_basis("nmf3", four)
    stored = s.basis("nmf3")
    assert stored.origin == "bases.h5:nmf3"
    data, report = specula.spc_encode(g, basis=stored, k=3, extra=1)
    assert report["basis"] == "bases.h5:nmf3+1" and specula.SpcBrdf(data).reference == "bases.h5:nmf3+1"
    assert specula.spc_encode(g, basis=four, k=3, reference="mine")[1]["basis"] == "mine"
    assert specula.spc_encode(g, basis=four, k=3)[1]["basis"] == "python"  # made in Python, saved nowhere


def test_fidelity_is_brdf_diff_suite(spgrid, tmp_path):
    g = specula.read_spgrid(spgrid)
    data, _ = specula.spc_encode(g, k=2)
    coded = tmp_path / "c.spc"
    specula.write_spc(coded, data)
    want = json.loads(cli("brdf-diff", spgrid, coded, "--json").stdout)
    got = specula.fidelity(g, specula.spc_decode(coded))
    for key in ("de00_mean", "de00_p95", "de00_max", "pixels", "hole_pixels", "cells", "hole_cells", "rel_rms_cos"):
        assert got[key] == pytest.approx(want[key], rel=1e-9, abs=1e-12), key
    assert got["worst_condition"] == want["worst_condition"] and len(got["conditions"]) == len(want["conditions"])
    # A grid against itself: nothing to see under any condition.
    same = specula.fidelity(g, g)
    assert same["de00_max"] == 0 and same["hole_cells"] == 0
