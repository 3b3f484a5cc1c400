"""Reads a specula store with h5py using only docs/store-format.md, and compares an image with a raw
float32 reference (H x W x B, band fastest) and its mask. Exit 0 on agreement."""
import sys

import h5py
import numpy as np

store, name, ref_path, mask_path, h, w, b = sys.argv[1:8]
h, w, b = int(h), int(w), int(b)
with h5py.File(store, "r") as f:
    assert f.attrs["specula_format"] == "specula-store", f.attrs["specula_format"]
    assert int(f.attrs["format_version"]) == 1
    img = f["images"][name]
    cube = img["cube"][...]
    mask = img["mask"][...].astype(bool)
    nm = img["wavelengths"][...]
    assert cube.dtype == np.float32 and cube.shape == (h, w, b), (cube.dtype, cube.shape)
    assert img["wavelengths"].attrs["units"] == "nm"
    assert int(img.attrs["valid_pixels"]) == int(mask.sum())
    assert img.attrs["kind"] == "image"
    ref = np.fromfile(ref_path, dtype="<f4").reshape(h, w, b)
    ref_mask = np.fromfile(mask_path, dtype=np.uint8).reshape(h, w).astype(bool)
    assert (mask == ref_mask).all()
    assert np.array_equal(cube[mask], ref[ref_mask])
    assert (cube[~mask] == 0).all()
    assert np.all(np.diff(nm) > 0)
print("ok")
