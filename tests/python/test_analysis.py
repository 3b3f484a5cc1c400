"""pca, nmf and project against numpy: the covariance's eigendecomposition, explicit projection formulas and
scipy's NNLS; saved bases against what the CLI saves."""
import json

import numpy as np
import pytest
import scipy.optimize

from conftest import cli, cli_error, valid_spectra_h5
import specula


def test_pca_is_the_covariance_eigendecomposition(db):
    s = specula.Store(db)
    x = valid_spectra_h5(db, s.images).astype(np.float64)
    basis = specula.pca(db)
    assert basis.method == "pca" and basis.n == len(x) and basis.k == 31
    np.testing.assert_allclose(basis.mean, x.mean(axis=0), rtol=1e-10)
    cov = np.cov(x, rowvar=False)
    np.testing.assert_allclose(basis.covariance, cov, rtol=1e-8, atol=1e-12 * np.abs(cov).max())
    w, v = np.linalg.eigh(cov)
    w, v = w[::-1], v[:, ::-1]
    np.testing.assert_allclose(basis.eigenvalues, w, rtol=1e-7, atol=1e-9 * w[0])
    np.testing.assert_allclose(basis.explained_variance_ratio, w / w.sum(), rtol=1e-6, atol=1e-12)
    gaps = np.abs(np.diff(w[:6])) / w[0]
    for j in range(5):
        if gaps[j] > 1e-6 and (j == 0 or gaps[j - 1] > 1e-6):
            assert abs(abs(basis.components[j] @ v[:, j]) - 1) < 1e-8, j
    assert np.all(np.abs(basis.components).max(axis=1) == basis.components.max(axis=1))  # sign convention


def test_pca_of_a_collection_with_k_and_saved_as_the_cli_saves(db, tmp_path):
    out = tmp_path / "bases.h5"
    basis = specula.pca(db, collection="chips", k=4, name="chips-pca", output=out)
    assert basis.k == 4 and basis.source == "collection chips"
    cli("pca", db, "--collection", "chips", "-k", 4, "--name", "cli-pca", "-o", out)
    saved = specula.Store(out)
    assert saved.bases == ["chips-pca", "cli-pca"]
    a, b = saved.basis("chips-pca"), saved.basis("cli-pca")
    for field in ("mean", "eigenvalues", "components", "covariance", "second_moment"):
        np.testing.assert_array_equal(getattr(a, field), getattr(b, field))
    x = specula.Store(db).collection("chips").astype(np.float64)
    np.testing.assert_allclose(basis.eigenvalues, np.linalg.eigvalsh(np.cov(x, rowvar=False))[::-1], rtol=1e-8,
                               atol=1e-12)
    with pytest.raises(specula.InputError, match="basis 'chips-pca' exists already"):
        specula.pca(db, collection="chips", name="chips-pca", output=out)
    specula.pca(db, collection="chips", k=2, name="chips-pca", output=out, replace=True)
    assert specula.Store(out).basis("chips-pca").k == 2


def test_pca_errors(db, tmp_path):
    with pytest.raises(specula.UsageError, match="k = 40: the data has 31 bands"):
        specula.pca(db, k=40)
    with pytest.raises(specula.InputError) as e:
        specula.pca(db, collection="nope")
    assert str(e.value) == cli_error("pca", db, "--collection", "nope", "-o", tmp_path / "b.h5")


def test_project_pca_is_the_explicit_formula(db):
    s = specula.Store(db)
    basis = specula.pca(db)
    name = s.images[0]
    img, mask = s.image_and_mask(name)
    x = img.astype(np.float64)
    r = specula.project(basis, x, k=3, mask=mask)
    assert r["coefficients"].dtype == np.float64
    r32 = specula.project(basis, img, k=3, mask=mask)  # float32 in, float32 out: the float64 results rounded
    assert r32["coefficients"].dtype == r32["reconstruction"].dtype == r32["error"].dtype == np.float32
    np.testing.assert_array_equal(r32["reconstruction"], r["reconstruction"].astype(np.float32))
    v = basis.components[:3]
    c = (x - basis.mean) @ v.T
    recon = basis.mean + c @ v
    np.testing.assert_allclose(r["coefficients"], c, rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(r["reconstruction"], recon, rtol=1e-9, atol=1e-12)
    err = np.linalg.norm(x - recon, axis=-1)
    np.testing.assert_allclose(r["error"], err, rtol=1e-9, atol=1e-12)
    valid = mask.astype(bool)
    np.testing.assert_allclose(r["rms"], np.sqrt((err[valid] ** 2).sum() / (valid.sum() * 31)), rtol=1e-10)
    np.testing.assert_allclose(r["max_error"], err[valid].max(), rtol=1e-12)
    several = specula.project(basis, x, k=[1, 3, 31], mask=mask)  # as the CLI's -k 1,3,31
    assert sorted(several) == [1, 3, 31]
    np.testing.assert_array_equal(several[3]["reconstruction"], r["reconstruction"])
    assert several[1]["rms"] > several[3]["rms"] > several[31]["rms"]
    full = specula.project(basis, x[valid], k=31)
    np.testing.assert_allclose(full["reconstruction"], x[valid], atol=1e-9)  # all components: exact


def test_project_errors(db):
    basis = specula.pca(db, collection="chips")
    with pytest.raises(specula.UsageError, match="k is required"):
        specula.project(basis, np.zeros((2, 31)))
    with pytest.raises(specula.UsageError, match="k = 32: the basis has 31 components"):
        specula.project(basis, np.zeros((2, 31)), k=32)
    with pytest.raises(specula.UsageError, match="last axis"):
        specula.project(basis, np.zeros((2, 30)), k=2)


@pytest.fixture(scope="module")
def nmf3(db):
    return specula.nmf(db, 3, max_epochs=40, tol=1e-5)


def test_nmf_error_is_that_of_exact_nnls_coefficients(db, nmf3):
    basis, report = nmf3
    s = specula.Store(db)
    x = np.maximum(valid_spectra_h5(db, s.images).astype(np.float64), 0)  # negatives are clipped (the default)
    assert basis.method == "nmf" and basis.k == 3 and report["n"] == len(x)
    assert np.all(basis.components >= 0)
    np.testing.assert_allclose(np.linalg.norm(basis.components, axis=1), 1, rtol=1e-9)
    c = np.array([scipy.optimize.nnls(basis.components.T, row)[0] for row in x])
    rel = np.linalg.norm(x - c @ basis.components) / np.linalg.norm(x)
    np.testing.assert_allclose(report["rel_error"], rel, rtol=1e-6)
    _, sv, _ = np.linalg.svd(x, full_matrices=False)
    np.testing.assert_allclose(report["svd_bound"], np.sqrt((sv[3:] ** 2).sum()) / np.linalg.norm(x), rtol=1e-6)
    assert report["rel_error"] >= report["svd_bound"]
    assert all(a >= b - 1e-12 for a, b in zip(report["history"], report["history"][1:]))


def test_nmf_report_is_that_of_the_cli(db, nmf3, tmp_path):
    """specula.nmf()'s report and `specula nmf --json` are one object: same keys, same numbers for the same run."""
    _, report = nmf3
    out = tmp_path / "out.h5"
    cli("synth-db", "-o", out, "--images", "1", "--size", "4x4")
    printed = json.loads(cli("nmf", db, "-k", "3", "--max-epochs", "40", "--tol", "1e-5", "-o", out, "--json").stdout)
    assert set(report) == set(printed)
    assert report["basis"] is None and report["output"] is None and printed["basis"] == "nmf3"
    for key in ("n", "k", "bands", "epochs", "passes", "best_restart", "negatives", "values"):
        assert report[key] == printed[key], key
    np.testing.assert_allclose(report["history"], printed["history"], rtol=1e-12)
    np.testing.assert_allclose(report["components"], printed["components"], rtol=1e-12)
    assert len(report["history_seconds"]) == report["epochs"]


def test_project_nmf_is_scipy_nnls(db, nmf3):
    basis, _ = nmf3
    s = specula.Store(db)
    x = specula.Store(db).collection("chips").astype(np.float64)
    r = specula.project(basis, x)
    c = np.array([scipy.optimize.nnls(basis.components.T, row)[0] for row in x])
    np.testing.assert_allclose(r["coefficients"], c, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(r["reconstruction"], c @ basis.components, rtol=1e-7, atol=1e-9)
    with pytest.raises(specula.UsageError, match="projects onto all of its 3 components"):
        specula.project(basis, x, k=2)


def test_nmf_saves_its_basis_and_reports_epochs(db, tmp_path):
    out = tmp_path / "nmf.h5"
    epochs = []
    basis, report = specula.nmf(db, 2, collection="chips", max_epochs=5, name="chips-nmf2", output=out,
                                on_epoch=epochs.append)
    assert [e["epoch"] for e in epochs] == list(range(1, len(epochs) + 1)) and len(epochs) >= 1
    saved = specula.Store(out).basis("chips-nmf2")
    np.testing.assert_array_equal(saved.components, basis.components)
    assert not (tmp_path / "nmf.h5.nmf-chips-nmf2.checkpoint").exists()


def test_nmf_errors_are_the_libraries_messages(db, tmp_path):
    with pytest.raises(specula.UsageError) as e:
        specula.nmf(db, 2, init="svd")
    assert str(e.value) == cli_error("nmf", db, "-k", 2, "--init", "svd", "-o", tmp_path / "n.h5")
    with pytest.raises(specula.UsageError):
        specula.nmf(db, 0)

    def stop(_):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        specula.nmf(db, 2, collection="chips", on_epoch=stop)


def test_ctrl_c_stops_nmf_and_raises_the_librarys_interrupted(db, tmp_path):
    import os
    import signal

    def on_epoch(e):
        if e["epoch"] == 1:
            os.kill(os.getpid(), signal.SIGINT)

    # Python's own Ctrl-C handler, as an interactive session has it: a process started in the background by a
    # non-interactive shell inherits SIGINT ignored, and Python then leaves it ignored.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        with pytest.raises(specula.Interrupted) as e:
            specula.nmf(db, 3, max_epochs=100000, tol=0, name="stopped", output=tmp_path / "n.h5", on_epoch=on_epoch)
    finally:
        signal.signal(signal.SIGINT, previous)
    assert isinstance(e.value, KeyboardInterrupt) and isinstance(e.value, specula.Error)
    assert str(e.value).startswith("interrupted") and "\n" not in str(e.value)
    assert not (tmp_path / "n.h5").exists()  # nothing half-written
    assert specula.pca(db, collection="chips").k == 31  # the stop request was cleared
