"""specula.Store and Store.blocks() against h5py reading the same objects through the root's external links."""
import concurrent.futures

import h5py
import numpy as np
import pytest

from conftest import cli_error, valid_spectra_h5
import specula


def test_lists_objects_as_h5py_sees_them(db):
    s = specula.Store(db)
    with h5py.File(db, "r") as f:
        assert s.images == sorted(f["images"])
        assert s.collections == ["chips"]
        assert s.samples == ["scan"]
        assert s.grids == ["rp"] and s.bases == ["pca"] and s.coefficients == ["coef"]
    assert s.format_version == 2
    assert ("collection", "chips") in s.objects()


def test_image_info_matches_the_files_attributes(db):
    s = specula.Store(db)
    name = s.images[0]
    info = s.info(name)
    with h5py.File(db, "r") as f:
        g = f["images"][name]
        assert (info["height"], info["width"], info["bands"]) == g["cube"].shape
        np.testing.assert_array_equal(info["wavelengths"], g["wavelengths"][...])
        assert info["valid_pixels"] == int(g["mask"][...].sum()) == int(g.attrs["valid_pixels"])
        assert info["chunk_rows"] == g["cube"].chunks[0]
    assert info["kind"] == "image" and info["provenance"]["importer"] == "synth-db"
    assert s.info("collection/chips")["size"] == 40


def test_image_mask_collection_samples_as_arrays(db):
    s = specula.Store(db)
    name = s.images[1]
    with h5py.File(db, "r") as f:
        cube = f["images"][name]["cube"][...]
        mask = f["images"][name]["mask"][...]
        chips = f["collections"]["chips"]["spectra"][...]
        angles = f["samples"]["scan"]["angles"][...]
        values = f["samples"]["scan"]["values"][...]
    np.testing.assert_array_equal(s.image(name), cube)
    assert s.image(name).dtype == np.float32
    np.testing.assert_array_equal(s.mask(name), mask)
    assert 0 < mask.sum() < mask.size  # the synthetic scenes mask some pixels
    img, m = s.image_and_mask(name)
    np.testing.assert_array_equal(m, mask)
    y, x = np.argwhere(mask == 0)[0]
    assert s.pixel(name, int(x), int(y)) is None
    y, x = np.argwhere(mask == 1)[0]
    np.testing.assert_array_equal(s.pixel(name, int(x), int(y)), cube[y, x])
    np.testing.assert_array_equal(s.collection("chips"), chips)
    assert s.collection_names("chips")[:2] == ["chip0", "chip1"]
    a, v = s.samples_data("scan")
    np.testing.assert_array_equal(a, angles)
    np.testing.assert_array_equal(v, values)
    a, v = s.samples_data("scan", first=10, count=5)
    np.testing.assert_array_equal(a, angles[10:15])


def test_grid_basis_and_coefficient_map_as_h5py_reads_them(db):
    s = specula.Store(db)
    with h5py.File(db, "r") as f:
        brdf = f["grids"]["rp"]["brdf"][...]
        b = {k: f["bases"]["pca"][k][...] for k in ("components", "mean", "eigenvalues", "covariance", "wavelengths")}
        coef = f["coefficients"]["coef"]["coefficients"][...]
        cmask = f["coefficients"]["coef"]["mask"][...]
        image = f["coefficients"]["coef"].attrs.get("image")
    g = s.grid("rp")
    np.testing.assert_array_equal(g.values, brdf)
    np.testing.assert_array_equal(g.wavelengths, [420, 520, 620, 720])
    assert s.info("rp")["kind"] == "grid" and s.info("rp")["bands"] == 4
    basis = s.basis("pca")
    for k, v in b.items():
        np.testing.assert_array_equal(getattr(basis, k), v)
    assert s.info("basis/pca")["method"] == "pca" and s.info("pca")["k"] == 31
    c, m = s.coefficient_map("coef")
    np.testing.assert_array_equal(c, coef)
    np.testing.assert_array_equal(m, cmask)
    info = s.info("coef")
    assert info["k"] == 4 and info["basis"] == "pca" and info["method"] == "pca"
    if image is not None:
        assert info["image"] == image
    # The map holds eq 7.2's coefficients of the image's valid pixels on the basis's first 4 components.
    cube = s.image(info["image"]).astype(np.float64)
    valid = m.astype(bool)
    expected = (cube[valid] - basis.mean) @ basis.components[:4].T
    np.testing.assert_allclose(c[valid], expected, rtol=1e-4, atol=1e-5 * np.abs(expected).max())
    assert np.all(c[~valid] == 0)
    cb = s.coefficient_basis("coef")
    np.testing.assert_array_equal(cb.components, basis.components[:4])


def test_blocks_stream_every_valid_spectrum_in_chunk_order(db):
    s = specula.Store(db)
    blocks = s.blocks()
    got = np.concatenate(list(blocks))
    assert got.dtype == np.float32 and got.shape[1] == 31
    np.testing.assert_array_equal(got, valid_spectra_h5(db, blocks.sources))
    assert blocks.spectra == got.shape[0]
    np.testing.assert_array_equal(blocks.wavelengths, s.info(s.images[0])["wavelengths"])


def test_each_block_is_the_valid_spectra_of_its_chunk_rows(db):
    s = specula.Store(db)
    blocks = s.blocks(min_block_pixels=1)  # one chunk row-group per block
    with h5py.File(db, "r") as f:
        for i in range(len(blocks)):
            g = f["images"][blocks.block_source(i)]
            rows = g["cube"].chunks[0]
            y0 = blocks.block_first_row(i)
            assert y0 % rows == 0
            cube = g["cube"][y0:y0 + rows]
            mask = g["mask"][y0:y0 + rows].astype(bool)
            np.testing.assert_array_equal(blocks.read(i), cube[mask])


def test_blocks_float64_selection_and_collection(db):
    s = specula.Store(db)
    name = s.images[2]
    b64 = np.concatenate(list(s.blocks(images=name, dtype=np.float64)))
    assert b64.dtype == np.float64
    np.testing.assert_array_equal(b64, valid_spectra_h5(db, [name]).astype(np.float64))
    b = s.blocks(images=[s.images[0], s.images[2]])
    assert b.sources == [s.images[0], s.images[2]]
    chips = np.concatenate(list(s.blocks(collection="chips")))
    np.testing.assert_array_equal(chips, s.collection("chips"))
    with h5py.File(db, "r") as f:
        values = f["samples"]["scan"]["values"][...]
    samples = s.blocks(samples="scan", dtype=np.float64)
    assert samples.bands == values.shape[1] and samples.units == s.info("samples/scan")["units"]
    np.testing.assert_array_equal(np.concatenate(list(samples)), values.astype(np.float64))


def test_blocks_read_from_many_threads_agree(db):
    s = specula.Store(db)
    blocks = s.blocks(min_block_pixels=1)
    expected = [blocks.read(i) for i in range(len(blocks))]
    with concurrent.futures.ThreadPoolExecutor(4) as pool:
        got = list(pool.map(blocks.read, range(len(blocks))))
    for e, g in zip(expected, got):
        np.testing.assert_array_equal(e, g)
    assert sum(len(g) for g in got) == blocks.spectra


def test_errors_are_the_clis_messages_or_name_full_paths(db, tmp_path):
    missing = tmp_path / "missing.h5"
    with pytest.raises(FileNotFoundError) as e:
        specula.Store(missing)
    assert isinstance(e.value, specula.InputError) and isinstance(e.value, specula.MissingFileError)
    assert str(e.value).startswith(str(missing) + ": no such file")
    with pytest.raises(KeyError) as e:
        specula.Store(db).image("nope")
    assert isinstance(e.value, specula.InputError)
    assert str(e.value) == f"{db}: no image 'nope' (its images: " + ", ".join(specula.Store(db).images) + ")"
    with pytest.raises(KeyError, match="no collection 'nope'"):
        specula.Store(db).blocks(collection="nope")
    with pytest.raises(KeyError, match=f"^{db}: no object 'nope'"):
        specula.Store(db).info("nope")
    with pytest.raises(specula.InputError) as e:
        specula.Store(db).blocks(images="nothing*")
    assert str(e.value) == cli_error("pca", db, "--images", "nothing*", "-o", tmp_path / "b.h5")
    assert "\n" not in str(e.value)
    with pytest.raises(specula.UsageError, match="dtype"):
        specula.Store(db).blocks(dtype=np.int32)


def test_wrong_argument_types_get_short_messages(db):
    big = np.zeros((200, 31))
    for call in (lambda: specula.project(big, big, k=3), lambda: specula.brdf_lookup(big, 0, 0, 0, 0),
                 lambda: specula.write_spgrid("x.spgrid", big), lambda: specula.Store(big)):
        with pytest.raises(TypeError) as e:
            call()
        assert len(str(e.value)) < 120 and "\n" not in str(e.value), str(e.value)


def test_exception_classes():
    assert issubclass(specula.InputError, specula.Error) and issubclass(specula.InputError, ValueError)
    assert issubclass(specula.UsageError, specula.Error) and issubclass(specula.UsageError, ValueError)
    assert issubclass(specula.MissingFileError, specula.InputError)
    assert issubclass(specula.MissingFileError, FileNotFoundError)
    assert issubclass(specula.MissingObjectError, specula.InputError) and issubclass(specula.MissingObjectError, KeyError)
    assert issubclass(specula.LibraryError, specula.Error)
    assert issubclass(specula.Error, Exception)


def test_blocks_iterate_again_and_say_what_they_are(db):
    s = specula.Store(db)
    blocks = s.blocks(min_block_pixels=1)
    first = [b.copy() for b in blocks]
    second = list(blocks)
    assert len(first) == len(blocks) > 1
    for a, b in zip(first, second):
        np.testing.assert_array_equal(a, b)
    r = repr(blocks)
    assert r.startswith("<specula.Blocks ") and f"{blocks.spectra} spectra x 31 bands" in r and "float32" in r


def test_masked_pixels_filled_on_request(db):
    s = specula.Store(db)
    name = s.images[0]
    img, mask = s.image(name, masked=np.nan), s.mask(name).astype(bool)
    assert (~mask).any()
    assert np.isnan(img[~mask]).all() and not np.isnan(img[mask]).any()
    np.testing.assert_array_equal(img[mask], s.image(name)[mask])
