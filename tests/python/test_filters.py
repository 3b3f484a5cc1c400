"""specula.design_filters, read_filters and write_filters (docs/python.md, docs/filters.md): the design equals the
CLI's filter CSV for the same arguments, its expected error equals a numpy computation of the Wiener error from the
returned curves (system integrated here, independently of the library), and the filter CSV round-trips and is
refused with one clear error."""
import json

import numpy as np
import pytest

import specula
from conftest import cli, cli_error

BANDS = np.arange(420, 721, 10, dtype=float)


@pytest.fixture(scope="module")
def spectra_store(tmp_path_factory):
    """60 smooth reflectances (Gaussian bumps on a floor) as collection 'spectra', a PCA basis and an NMF basis of
    them, made by the CLI."""
    d = tmp_path_factory.mktemp("filters")
    rows = []
    for i in range(60):
        c, w, base = 430 + 5.0 * i, 40 + (i % 7) * 15, 0.05 + 0.01 * (i % 9)
        rows.append(base + 0.6 * np.exp(-0.5 * ((BANDS - c) / w) ** 2))
    with open(d / "spectra.csv", "w") as f:
        f.write("name," + ",".join(str(int(b)) for b in BANDS) + "\n")
        for i, r in enumerate(rows):
            f.write(f"s{i}," + ",".join(f"{v:.5f}" for v in r) + "\n")
    path = d / "db.h5"
    cli("import", d / "spectra.csv", "--name", "spectra", "-o", path)
    cli("pca", path, "--collection", "spectra", "--name", "pca")
    cli("nmf", path, "--collection", "spectra", "-k", 4, "--name", "nmf4")
    return path


def _sensitivity(nm, kelvin=3200.0):
    """The design's light times the simulated camera's quantum efficiency (docs/filters.md), up to a constant:
    a Planck blackbody and 0.25 + 0.6 exp(-((l - 550) / 140)^2), tabulated every 2 nm and linear between."""
    grid = np.arange(380.0, 780.5, 2.0)
    c2 = 6.62607015e-34 * 299792458.0 / 1.380649e-23 * 1e9
    planck = grid ** -5.0 / np.expm1(c2 / (grid * kelvin))
    qe = 0.25 + 0.6 * np.exp(-(((grid - 550.0) / 140.0) ** 2))
    return np.interp(nm, grid, planck * qe)


def _normalised_system(wavelengths, transmission, bands):
    """A[k, b] = integral of T_k s hat_b over an open filter's white reading, by the trapezoid rule on 0.02 nm."""
    nm = np.arange(bands[0], bands[-1] + 1e-9, 0.02)
    s = _sensitivity(nm)
    hats = np.array([np.interp(nm, bands, np.eye(len(bands))[b]) for b in range(len(bands))])
    t = np.array([np.interp(nm, wavelengths, row, left=0.0, right=0.0) for row in transmission])
    a = np.trapz(t[:, None, :] * hats[None, :, :] * s, nm, axis=2)
    return a / np.trapz(s, nm)


def _expected_rms(a, prior, spectra, noise, floor):
    """Per spectrum sqrt((|x - R A x|^2 + |R diag(sigma)|_F^2) / B) with the Wiener R and
    sigma_k = noise * max(throughput_k, floor)."""
    sigma = noise * np.maximum(a.sum(axis=1), floor)
    r = prior @ a.T @ np.linalg.inv(a @ prior @ a.T + np.diag(sigma ** 2))
    e = spectra.T - r @ a @ spectra.T
    return np.sqrt(((e ** 2).sum(axis=0) + ((r * sigma) ** 2).sum()) / a.shape[1])


def test_design_matches_the_cli_and_its_expected_error_matches_numpy(spectra_store, tmp_path):
    d = specula.design_filters(spectra_store, "pca", k=4)
    assert d["names"] == ["opt1", "opt2", "opt3", "opt4"]
    t, nm = d["transmission"], d["wavelengths"]
    assert t.shape == (4, nm.size) and t.dtype == np.float64
    assert (t >= 0).all() and t.max() <= 0.9 + 1e-12
    assert np.array_equal(d["bands"], BANDS)
    # The CLI writes the same curves (to the CSV's six decimals) for the same arguments.
    report = json.loads(cli("filters", "design", spectra_store, "--basis", "pca", "-k", 4, "-o", tmp_path / "cli.csv",
                            "--json").stdout)
    c = specula.read_filters(tmp_path / "cli.csv")
    # ... and the same report: every field of --json but the output file, equal.
    assert set(report) - set(d) == {"output"}
    for key, value in report.items():
        if key != "output":
            assert (list(d[key]) if key == "throughput" else d[key]) == value, key
    assert c["names"] == d["names"]
    assert np.array_equal(c["wavelengths"], nm)
    assert np.abs(c["transmission"] - t).max() <= 5e-7

    # The report against numpy: training = the collection without every fifth spectrum, held out = every fifth.
    x = specula.Store(spectra_store).collection("spectra").astype(np.float64)
    train, held = x[np.arange(len(x)) % 5 != 4], x[np.arange(len(x)) % 5 == 4]
    a = _normalised_system(nm, t, BANDS)
    assert np.allclose(d["throughput"], a.sum(axis=1), rtol=1e-6)
    prior = train.T @ train / len(train)
    for part, spectra in (("training", train), ("held_out", held)):
        rms = _expected_rms(a, prior, spectra, 0.002, 0.01)
        assert d[part]["count"] == len(spectra)
        assert d[part]["rms_mean"] == pytest.approx(rms.mean(), rel=1e-6)
        assert d[part]["rms_max"] == pytest.approx(rms.max(), rel=1e-6)
    assert d["held_out"]["spectra"] == "spectra (every fifth spectrum)"


def test_options_reach_the_design(spectra_store):
    nmf = specula.design_filters(spectra_store, "nmf4", k=3, method="nmf", peak=0.5, test="spectra")
    assert nmf["names"] == ["nmf1", "nmf2", "nmf3"]
    assert nmf["transmission"].shape[0] == 3 and nmf["transmission"].max() == pytest.approx(0.5, abs=1e-9)
    assert nmf["held_out"]["spectra"] == "spectra" and nmf["held_out"]["count"] == 60
    # More camera noise can only raise the expected error of the same design's noise term.
    quiet = specula.design_filters(spectra_store, "nmf4", k=3, method="nmf", noise=0.0)
    loud = specula.design_filters(spectra_store, "nmf4", k=3, method="nmf", noise=0.05)
    assert quiet["held_out"]["noise_rms"] == 0 and loud["held_out"]["noise_rms"] > 0
    assert loud["held_out"]["rms_mean"] > quiet["held_out"]["rms_mean"]
    with pytest.raises(specula.UsageError, match="method 'fancy'"):
        specula.design_filters(spectra_store, "pca", method="fancy")
    with pytest.raises(specula.UsageError, match="k must be 1 to 31"):
        specula.design_filters(spectra_store, "pca", k=0)
    with pytest.raises(specula.InputError):
        specula.design_filters(spectra_store, "nope")


def test_filter_csv_round_trip_and_refusals(tmp_path):
    nm = np.array([400.0, 500.0, 600.0, 740.0])
    t = np.array([[0.1, 0.9, 0.2, 0.0], [0.0, 0.05, 0.5, 1.0]])
    p = tmp_path / "f.csv"
    specula.write_filters(p, t, nm, names=["blue", "red"])
    back = specula.read_filters(p)
    assert back["names"] == ["blue", "red"]
    assert np.array_equal(back["wavelengths"], nm) and np.array_equal(back["transmission"], t)
    # One curve as a 1-D array, default names; the file simulate-capture reads.
    specula.write_filters(tmp_path / "one.csv", t[1], nm)
    assert specula.read_filters(tmp_path / "one.csv")["names"] == ["F1"]

    bad = tmp_path / "bad.csv"
    for args, message in (((-t, nm), "transmits -0.1; a transmission is 0 to 1"),
                          ((t, nm[::-1]), "wavelengths must be positive and increase"),
                          ((t, nm, ["a,b", "c"]), "has no commas"),
                          ((t, nm[:3]), "4 values per filter, wavelengths 3")):
        with pytest.raises(specula.UsageError, match=message):
            specula.write_filters(bad, *args)
        assert not bad.exists()
    bad.write_text("wavelength_nm,a\n400,0.5\n500,1.5\n")
    with pytest.raises(specula.InputError, match=r"bad.csv:3: filter 'a' transmits 1.5"):
        specula.read_filters(bad)
    with pytest.raises(specula.MissingFileError):
        specula.read_filters(tmp_path / "absent.csv")
    # The CLI refuses the same file with the same line.
    assert "bad.csv:3: filter 'a' transmits 1.5" in cli_error("simulate-capture", "--filters", bad,
                                                               "-o", tmp_path / "cap")
