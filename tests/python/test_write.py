"""Writing stores from Python, checked with h5py reading the files through the root's external links: round trips,
transactions committed on a clean exit and rolled back on an exception, provenance, and pickling."""
import pickle

import h5py
import numpy as np
import pytest

import specula

NM = np.arange(400, 701, 10)


def cube_and_mask(seed=1, h=23, w=17):
    rng = np.random.default_rng(seed)
    cube = rng.uniform(0, 1, (h, w, NM.size)).astype(np.float32)
    mask = rng.uniform(size=(h, w)) > 0.2
    return cube, mask


def test_write_read_round_trip_checked_with_h5py(tmp_path):
    path = tmp_path / "w.h5"
    cube, mask = cube_and_mask()
    spectra = cube[0].astype(np.float64)
    with specula.Store(path, mode="a") as s:
        assert s.images == []  # created by the commit
        s.write_image("scene", cube, NM, mask=mask, units="reflectance")
        s.write_collection("chips", spectra, "400:700:10", names=[f"c{i}" for i in range(len(spectra))])
    assert s.images == ["scene"] and s.collections == ["chips"]  # listed without reopening
    with h5py.File(path, "r") as f:
        g = f["images"]["scene"]
        got, got_mask = g["cube"][...], g["mask"][...].astype(bool)
        np.testing.assert_array_equal(got_mask, mask)
        np.testing.assert_array_equal(got[mask], cube[mask])
        np.testing.assert_array_equal(f["collections"]["chips"]["spectra"][...], spectra.astype(np.float32))
        np.testing.assert_array_equal(f["collections"]["chips"]["wavelengths"][...], NM)
    info = s.info("scene")
    assert info["units"] == "reflectance" and info["valid_pixels"] == mask.sum()
    np.testing.assert_array_equal(info["wavelengths"], NM)
    assert info["provenance"]["importer"] == "python"
    assert info["provenance"]["command_line"].startswith("python: specula.Store.write_image")
    img = specula.Store(path).image("scene", masked=np.nan)
    np.testing.assert_array_equal(img[mask], cube[mask])
    assert np.isnan(img[~mask]).all()
    assert specula.Store(path).collection_names("chips")[:2] == ["c0", "c1"]
    np.testing.assert_array_equal(np.concatenate(list(s.blocks(images="scene"))), cube[mask])


def test_writes_outside_with_commit_at_once_and_replace(tmp_path):
    path = tmp_path / "w.h5"
    cube, _ = cube_and_mask(2)
    s = specula.Store(path, mode="a")
    s.write_image("a", cube, NM)
    assert specula.Store(path).images == ["a"]
    with pytest.raises(specula.InputError, match="exists already"):
        s.write_image("a", cube * 2, NM)
    s.write_image("a", cube * 2, NM, replace=True)
    np.testing.assert_array_equal(specula.Store(path).image("a"), cube * 2)
    s.remove("a")
    assert s.images == [] and specula.Store(path).images == []
    with pytest.raises(specula.UsageError, match="read-only"):
        specula.Store(path).write_image("b", cube, NM)


def test_an_exception_rolls_the_transaction_back(tmp_path):
    path = tmp_path / "w.h5"
    cube, mask = cube_and_mask(3)
    with pytest.raises(RuntimeError):
        with specula.Store(path, mode="a") as s:
            s.write_image("never", cube, NM)
            raise RuntimeError("stop")
    assert not path.exists()  # a new store appears only with its first commit
    with specula.Store(path, mode="a") as s:
        s.write_image("kept", cube, NM, mask=mask)
    before = path.read_bytes()
    with pytest.raises(ZeroDivisionError):
        with s:
            s.write_image("lost", cube, NM)
            s.remove("kept")
            1 / 0
    assert path.read_bytes() == before
    assert specula.Store(path).images == ["kept"] and s.images == ["kept"]
    with h5py.File(path, "r") as f:
        assert list(f["images"].keys()) == ["kept"]
    with s:
        s.write_image("abandoned", cube, NM)
        s.close()  # abandons the transaction; the block's end then has nothing to commit
    assert s.images == ["kept"]
    bad = cube.copy()
    bad[0, 0, 0] = np.inf
    with pytest.raises(specula.InputError):
        s.write_image("inf", bad, NM)  # a single write that fails leaves nothing
    assert specula.Store(path).images == ["kept"]


def test_other_writers_commits_seen_after_refresh(tmp_path):
    path = tmp_path / "w.h5"
    cube, _ = cube_and_mask(4)
    reader = specula.Store(path, mode="a")
    specula.Store(path, mode="a").write_image("x", cube, NM)
    assert reader.images == ["x"]  # committed by this process
    other = specula.Store(path)
    with h5py.File(path, "r") as f:
        assert "x" in f["images"]
    reader.refresh()
    assert other.images == reader.images == ["x"]


def test_bases_and_grids_write_and_pickle(tmp_path, db):
    basis = specula.pca(db, collection="chips")
    assert basis.components.flags.writeable is False  # properties are read-only views
    copy = pickle.loads(pickle.dumps(basis))
    for field in ("mean", "components", "eigenvalues", "explained_variance_ratio", "covariance", "second_moment"):
        np.testing.assert_array_equal(getattr(copy, field), getattr(basis, field))
    assert (copy.method, copy.n, copy.source) == (basis.method, basis.n, basis.source)
    path = tmp_path / "w.h5"
    rng = np.random.default_rng(5)
    grid = specula.Grid([400, 500, 600], rng.uniform(0, 1, (3, 90, 90, 180)).astype(np.float32), scale=0.25)
    assert grid.values.flags.writeable is False
    g2 = pickle.loads(pickle.dumps(grid))
    np.testing.assert_array_equal(g2.values, grid.values)
    assert g2.scale == 0.25 and g2.bands == 3
    with specula.Store(path, mode="a") as s:
        s.write_basis("b", basis)
        s.write_grid("g", grid)
    stored = s.basis("b")
    assert stored.origin == "w.h5:b" and pickle.loads(pickle.dumps(stored)).origin == "w.h5:b"
    np.testing.assert_array_equal(stored.components, basis.components)
    with h5py.File(path, "r") as f:
        np.testing.assert_array_equal(f["bases"]["b"]["mean"][...], basis.mean)
    np.testing.assert_array_equal(s.grid("g").values, grid.values)
    assert s.grid("g").scale == 0.25


def test_float32_in_float32_out(db):
    basis = specula.pca(db, collection="chips")
    x = specula.Store(db).collection("chips")
    r32, r64 = specula.project(basis, x, k=3), specula.project(basis, x.astype(np.float64), k=3)
    assert r32["coefficients"].dtype == np.float32 and r64["coefficients"].dtype == np.float64
    np.testing.assert_allclose(r32["reconstruction"], r64["reconstruction"], rtol=1e-6, atol=1e-6)


def test_to_xarray_has_wavelength_coordinates(tmp_path):
    xr = pytest.importorskip("xarray")
    path = tmp_path / "w.h5"
    cube, mask = cube_and_mask(6)
    with specula.Store(path, mode="a") as s:
        s.write_image("scene", cube, NM, mask=mask, units="reflectance")
        s.write_collection("chips", cube[1], NM, names=[f"c{i}" for i in range(cube.shape[1])])
    da = s.to_xarray("scene")
    assert isinstance(da, xr.DataArray) and da.dims == ("y", "x", "wavelength") and da.attrs["units"] == "reflectance"
    np.testing.assert_array_equal(da["wavelength"].values, NM)
    np.testing.assert_array_equal(da.sel(wavelength=550).values[mask], cube[..., 15][mask])
    assert np.isnan(da.values[~mask]).all()
    c = s.to_xarray("chips")
    assert c.dims == ("spectrum", "wavelength") and list(c["spectrum"].values[:2]) == ["c0", "c1"]
    np.testing.assert_array_equal(c.values, cube[1])
    g = specula.Grid([400, 500], np.full((2, 90, 90, 180), -1, np.float32), scale=2.0)
    assert np.isnan(g.to_xarray().values).all()
