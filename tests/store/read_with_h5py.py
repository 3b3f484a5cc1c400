"""Reads a specula store with h5py using only docs/store-format.md, and compares an image with a raw
float32 reference (H x W x B, band fastest) and its mask; then checks every object through the root's
external links against /index, with zlib's CRC-32 of each data file. Exit 0 on agreement."""
import json
import os
import sys
import zlib

import h5py
import numpy as np

store, name, ref_path, mask_path, h, w, b = sys.argv[1:8]
h, w, b = int(h), int(w), int(b)
os.chdir("/")  # links resolve beside the root, not in the working directory
with h5py.File(store, "r") as f:
    assert f.attrs["specula_format"] == "specula-store", f.attrs["specula_format"]
    assert int(f.attrs["format_version"]) == 2
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

    index = json.loads(f["index"][()].decode() if isinstance(f["index"][()], bytes) else f["index"][()])
    data_dir = os.path.join(os.path.dirname(os.path.abspath(store)), f.attrs["data_dir"])
    listed = set()
    for o in index["objects"]:
        link = f[o["kind"]].get(o["name"], getlink=True)
        assert isinstance(link, h5py.ExternalLink), link
        assert link.filename == f.attrs["data_dir"] + "/" + o["file"], (link.filename, o["file"])
        assert link.path == "/" + o["kind"] + "/" + o["name"]
        with open(os.path.join(data_dir, o["file"]), "rb") as df:
            data = df.read()
        assert len(data) == o["bytes"] and "%08x" % zlib.crc32(data) == o["crc32"], o
        assert "kind" in f[o["kind"]][o["name"]].attrs  # the object opens through the link
        listed.add((o["kind"], o["name"]))
    for kind in ("images", "collections", "samples", "grids", "bases", "coefficients", "acquire"):
        for n in f.get(kind, {}):
            assert (kind, n) in listed, (kind, n)
    assert len(listed) == int(sys.argv[8]), (len(listed), sys.argv[8])
    if ("collections", "chips") in listed:
        c = f["collections/chips"]
        assert c["spectra"].shape == (3, 31) and list(c["names"].asstr()[...]) == ["a", "b", "c"]
    if ("bases", "pca") in listed:
        assert f["bases/pca/components"].shape == (2, 31)
print("ok")
