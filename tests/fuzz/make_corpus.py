#!/usr/bin/python3
"""Writes the seed corpora of tests/fuzz/corpus/<target>/ from the layouts the reader tests use as fixtures
(tests/store/io/*_test.cpp), a few hundred bytes each. Run with Debian's python3 (numpy, scipy, h5py, gdal):
/usr/bin/python3 tests/fuzz/make_corpus.py. Crash reproducers found by fuzzing are added by hand beside them."""
import os
import struct
import zlib

import h5py
import numpy as np
import scipy.io

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus")
SEP = b"\n--next file--\n"  # entries.h kFileSeparator


def put(target, name, data):
    os.makedirs(os.path.join(HERE, target), exist_ok=True)
    with open(os.path.join(HERE, target, name), "wb") as f:
        f.write(data if isinstance(data, bytes) else data.encode())


def floats(values, big_endian=False):
    return struct.pack((">" if big_endian else "<") + "%df" % len(values), *values)


# envi: header + data. A library (envi_library_test.cpp: wavelengths out of order, big endian) and a bip image
# with bbl (EnviBbl test).
lib_header = (b"ENVI\ndescription = {\n  Spectral Library}\nsamples = 5\nlines   = 3\nbands   = 1\n"
              b"header offset = 0\nfile type = ENVI Spectral Library\ndata type = 4\ninterleave = bsq\n"
              b"byte order = 1\nwavelength units = Micrometers\nwavelength = {\n 0.4000, 0.5000, 0.9000,\n 0.7000, 0.6000}\n"
              b"spectra names = {\n Alunite GDS84 Na03, Kaolinite CM9,\n Dry Grass}\nbbl = {1, 1, 0, 1, 1}\n")
lib_values = [0.125 * (s + 1) + 0.0078125 * b for s in range(3) for b in range(5)]
put("envi", "library-bbl", lib_header + SEP + floats(lib_values, True))
img_header = (b"ENVI\nsamples = 2\nlines = 1\nbands = 4\nheader offset = 0\nfile type = ENVI Standard\n"
              b"data type = 4\ninterleave = bip\nbyte order = 0\nwavelength units = Nanometers\n"
              b"wavelength = {450, 550, 650, 750}\nfwhm = {5, 6, 7, 8}\nbbl = {1.0, 0.0, 1.0, 0.0}\n")
put("envi", "image-bip-bbl", img_header + SEP + floats([10 * x + b + 1 for x in range(2) for b in range(4)]))
put("envi", "image-u16-bil", b"ENVI\nsamples = 2\nlines = 2\nbands = 2\ndata type = 12\ninterleave = bil\n"
    b"byte order = 1\ndata ignore value = 0\nwavelength = {0.5, 0.6}\n" + SEP + struct.pack(">8H", *range(8)))

# mask: ENVI byte image (mask_test.cpp) and PNGs.
put("mask", "envi-bytes", b"ENVI\nsamples = 3\nlines = 2\nbands = 1\nheader offset = 0\nfile type = ENVI Standard\n"
    b"data type = 1\ninterleave = bsq\nbyte order = 0\ndata ignore value = 7\n" + SEP + bytes([0, 1, 255, 0, 7, 1]))


def png(width, height, colour_type, depth, rows):
    def chunk(kind, body):
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xffffffff)
    raw = b"".join(b"\0" + r for r in rows)
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, depth, colour_type, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


put("mask", "rgb8.png", png(2, 1, 2, 8, [bytes([9, 0, 0, 0, 200, 200])]))
put("mask", "grey16.png", png(3, 2, 0, 16, [struct.pack(">3H", 0, 1, 65535), struct.pack(">3H", 7, 0, 2)]))

# text_library: USGS wavelengths + spectra, ECOSTRESS pair (text_library_test.cpp).
def splib(title, values):
    return (title + "\n" + "".join("   " + v + "\n" for v in values)).encode()


put("text_library", "usgs", SEP.join([
    splib("splib07a Record=6: Wavelengths ASD 0.35-2.5 microns 2151 ch",
          ["0.350000", "0.400000", "0.450000", "0.500000", "0.550000"]),
    splib("splib07a Record=55: Alunite GDS84 Na03       ASDFRa AREF",
          ["-1.23e34", "0.2500000", "0.5000000", "0.7500000", "0.1250000"]),
    splib("splib07a Record=3380: Kaolinite CM9          ASDFRb AREF",
          ["0.0625000", "0.3750000", "0.6250000", "-1.2300000e+34", "0.8750000"])]))


def ecostress(name, rows):
    s = ("Name: " + name + "\nType: Mineral\nClass: Silicate\nOwner: JHU\nWavelength Range: TIR\n"
         "Measurement: Directional (10 Degree) Hemispherical Reflectance\nFirst Column: X\nSecond Column: Y\n"
         "X Units: Wavelength (micrometers)\nY Units: Reflectance (percent)\nFirst X Value: " + rows[0][0] +
         "\nLast X Value: " + rows[-1][0] + "\nNumber of X Values: %d\nAdditional Information: none\n\n" % len(rows))
    return (s + "".join(x + "\t" + y + "\n" for x, y in rows)).encode()


put("text_library", "ecostress", SEP.join([
    ecostress("Acmite NaFe+3(SiO3)2", [("0.8", "50.0"), ("0.6", "25.0"), ("0.5", "12.5"), ("0.4", "6.25")]),
    ecostress("Dry grass", [("0.8", "80.0"), ("0.6", "60.0"), ("0.5", "40.0"), ("0.4", "20.0")])]))

# csv (csv_test.cpp).
put("csv", "header-names-quotes.csv", "\xEF\xBB\xBFname,400,500,600\r\nA,0.1,0.2,0.3\r\n\r\n\"B, \"\"quoted\"\"\", 1 ,2e-1,+3\r\n")
put("csv", "header-no-names.csv", "450,550\n0.5,0.25\n0.75,1\n")
put("csv", "transposed.csv", "wavelength_nm,\"dark skin\",light\n400,0.1,0.2\n410,0.3,0.4\n420,0.5,0.6\n")

# mat (mat_test.cpp layouts): v5 cube with wavelengths, v5 compressed bands-first with a mask, an unmixing
# benchmark, an ISETCam library, and a v7.3 cube.
rows, cols, bands = 3, 4, 5
cube = np.fromfunction(lambda r, c, b: 100.0 * r + 10.0 * c + b, (rows, cols, bands))
wl = np.arange(400.0, 400.0 + 10 * bands, 10.0).reshape(bands, 1)
tmp = os.path.join(HERE, "mat.tmp")


def save_mat(name, variables, compress=False):
    scipy.io.savemat(tmp, variables, do_compression=compress, format="5")
    with open(tmp, "rb") as f:
        put("mat", name, f.read())
    os.remove(tmp)


save_mat("v5-cube-wavelengths.mat", {"ref": cube, "wavelength": wl, "lbl": np.array([[1, 0, 1, 1]] * 3, np.uint8)})
save_mat("v5z-bands-first-single.mat",
         {"cube": np.ascontiguousarray(np.moveaxis(cube, 2, 0)).astype(np.float32), "bands": wl.ravel() / 1000.0},
         compress=True)
save_mat("v5-unmixing.mat", {"Y": np.arange(2 * 6, dtype=np.float64).reshape(2, 6), "nRow": 2.0, "nCol": 3.0,
                             "wavelengths": np.array([[450.0, 550.0]])})
save_mat("v5-library.mat", {"wavelength": wl, "data": np.arange(bands * 3, dtype=np.uint16).reshape(bands, 3)})

# v7.3: HDF5 behind MATLAB's 128-byte header in a 512-byte user block; datasets in MATLAB's reversed dim order.
with h5py.File(tmp, "w", userblock_size=512, libver="earliest") as h:
    for name, value in {"rad": np.ascontiguousarray(cube.transpose()), "bands": wl.ravel().reshape(1, bands)}.items():
        d = h.create_dataset(name, data=value)
        d.attrs["MATLAB_class"] = np.bytes_("double")
header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
header = header.ljust(116, b" ") + b"\0" * 8 + struct.pack("<H", 0x0200) + b"IM"
with open(tmp, "r+b") as f:
    f.write(header)
with open(tmp, "rb") as f:
    put("mat", "v73-cube-bands.mat", f.read())
os.remove(tmp)

# gdal: 4x3-pixel, 3-band GeoTIFFs: int16 with nodata (no wavelengths: the fallback grid), float32 with wavelength
# and fwhm metadata in micrometres; uncompressed and deflate (band-interleaved, tiled).
from osgeo import gdal  # noqa: E402  (Debian's python3-gdal)

gdal.UseExceptions()


def tif(name, dtype, options, fill):
    path = "/vsimem/" + name
    d = gdal.GetDriverByName("GTiff").Create(path, 4, 3, 3, dtype, options)
    fill(d)
    d = None
    f = gdal.VSIFOpenL(path, "rb")
    gdal.VSIFSeekL(f, 0, 2)
    size = gdal.VSIFTellL(f)
    gdal.VSIFSeekL(f, 0, 0)
    put("gdal", name, bytes(gdal.VSIFReadL(1, size, f)))
    gdal.VSIFCloseL(f)
    gdal.Unlink(path)


def int16_nodata(d):
    for b in range(3):
        band = d.GetRasterBand(b + 1)
        band.SetNoDataValue(-9999)
        values = np.arange(12, dtype=np.int16).reshape(3, 4) * 10 + b
        values[1, 2] = -9999
        band.WriteArray(values)


def float32_wavelengths(d):
    for b in range(3):
        band = d.GetRasterBand(b + 1)
        band.SetMetadataItem("wavelength", "%g" % (0.45 + 0.1 * b))
        band.SetMetadataItem("wavelength_units", "Micrometers")
        band.SetMetadataItem("fwhm", "0.01")
        band.WriteArray(np.arange(12, dtype=np.float32).reshape(3, 4) / 16 + b)


tif("int16-nodata.tif", gdal.GDT_Int16, [], int16_nodata)
tif("int16-nodata-deflate-band.tif", gdal.GDT_Int16, ["COMPRESS=DEFLATE", "INTERLEAVE=BAND"], int16_nodata)
tif("float32-wavelengths.tif", gdal.GDT_Float32, [], float32_wavelengths)
tif("float32-wavelengths-deflate-tiled.tif", gdal.GDT_Float32, ["COMPRESS=DEFLATE", "TILED=YES", "BLOCKXSIZE=16", "BLOCKYSIZE=16"],
    float32_wavelengths)

# spc: a format-1 file (tests/codec/data), a format-2 one (also tests/codec/data) and a format-3 one made by the CLI:
#   specula synth-brdf red-plastic --wavelengths 400:700:50 -o rp.spgrid
#   specula encode rp.spgrid --basis self -k 3 --step 0.05 -o rp-k3-v2.spc    # before format 3 existed
#   specula encode rp.spgrid --basis self -k 3 --step 0.05 -o rp-k3-v3.spc    # grazing factor 2 (the default)
# and a format-4 one (samples and their rule) from the Cornell acryl_blue measurement:
#   specula import ../shared/data/brdf/cornell/acryl_blue.brdf -o ab.h5
#   specula encode ab.h5:acryl_blue --samples-rule weights=wendland,k=4 --basis self -k 2 --step 0.2 \
#     -o acryl-blue-k2-v4.spc
# (kept as checked in: the encoder's bytes are not this script's to reproduce).
with open(os.path.join(os.path.dirname(HERE), "..", "codec", "data", "green-matte-7band-v1.spc"), "rb") as f:
    put("spc", "green-matte-7band-v1.spc", f.read())


# spgrid and merl (entries.h): a mode byte, then a header and a pattern the entry repeats to a whole file.
def spgrid_header(bands, version=1, dims=(90, 90, 180), scale=0.5):
    return b"SPECGRID" + struct.pack("<IIIIIId", version, bands, *dims, 0, scale)


put("spgrid", "one-band-crc-fixed", b"\0" + spgrid_header(1) + struct.pack("<df", 550.0, 0.5))
put("spgrid", "two-bands-crc-fixed", b"\0" + spgrid_header(2) + struct.pack("<ddf", 450.0, 650.0, -1.0))
put("spgrid", "two-bands-stale-crc", b"\2" + spgrid_header(2) + struct.pack("<ddf", 450.0, 650.0, 0.25))
put("spgrid", "truncated", b"\1" + spgrid_header(3) + struct.pack("<ddd", 450.0, 550.0, 650.0))
merl_header = struct.pack("<3i", 90, 90, 180)
put("merl", "quarter", b"\0" + merl_header + struct.pack("<d", 0.25))
put("merl", "no-data-and-values", b"\0" + merl_header + struct.pack("<3d", -1.0, 0.5, 2.0))
put("merl", "truncated", b"\1" + merl_header + struct.pack("<2d", 0.5, 0.5))

# RGL .bsdf tensor files (codec/rgl_tensor.h): fields 8-byte aligned, as specula's writer lays them out.
def tensor_file(fields):
    header = 12 + 2 + 4 + sum(2 + len(n) + 2 + 1 + 8 + 8 * len(a.shape) for n, a in fields)
    types = {np.dtype(np.uint8): 1, np.dtype(np.uint32): 5, np.dtype(np.float32): 10}
    at, offsets = (header + 7) // 8 * 8, []
    for _, a in fields:
        offsets.append(at)
        at = (at + a.nbytes + 7) // 8 * 8
    out = bytearray(b"tensor_file\0" + bytes([1, 0]) + struct.pack("<I", len(fields)))
    for (n, a), off in zip(fields, offsets):
        out += struct.pack("<H", len(n)) + n.encode() + struct.pack("<HBQ", len(a.shape), types[a.dtype], off)
        out += b"".join(struct.pack("<Q", e) for e in a.shape)
    out += bytes(at - len(out))
    for (_, a), off in zip(fields, offsets):
        out[off:off + a.nbytes] = a.astype(a.dtype.newbyteorder("<")).tobytes()
    return bytes(out)


def rgl(spectral):
    f32 = lambda v: np.asarray(v, dtype=np.float32)
    fields = [("version", np.array([1, 0], dtype=np.uint32)), ("description", np.frombuffer(b"seed", dtype=np.uint8)),
              ("phi_i", f32([0])), ("theta_i", f32([0, 1.2])),
              ("sigma", f32([[1, 0.9, 0.5], [1, 0.9, 0.5]])), ("ndf", f32([[2, 1, 0.1], [2, 1, 0.1]])),
              ("vndf", f32(np.arange(1, 17).reshape(1, 2, 2, 4) / 16)),
              ("luminance", f32(np.ones((1, 2, 2, 2))))]
    if spectral:
        fields += [("wavelengths", f32([450, 650])), ("spectra", f32(np.linspace(0.1, 0.9, 16).reshape(1, 2, 2, 2, 2)))]
    else:
        fields += [("rgb", f32(np.linspace(0.1, 0.9, 24).reshape(1, 2, 3, 2, 2)))]
    return tensor_file(fields + [("jacobian", np.array([1], dtype=np.uint8)), ("valid", np.array([255], dtype=np.uint8))])


put("rgl_bsdf", "spectral.bsdf", rgl(True))
put("rgl_bsdf", "rgb.bsdf", rgl(False))
put("rgl_bsdf", "truncated.bsdf", rgl(True)[:300])

# nbrdf: Keras weights of a 6 -> 21 -> 21 -> 3 network as Sztrajman et al. save them (tests/codec/nbrdf_test.cpp),
# float32, small values; a valid file, one with a wrong kernel shape, one with a NaN bias, and a truncated file.
def nbrdf(name, shapes, nan=False, truncate=0):
    path = os.path.join(HERE, "nbrdf-tmp.h5")
    rng = np.random.default_rng(7)
    with h5py.File(path, "w", libver="earliest") as f:
        for n, (k, b) in enumerate(shapes, 1):
            g = f.create_group("dense_%d/dense_%d" % (n, n))
            g["kernel:0"] = rng.normal(0, 0.3, k).astype(np.float32)
            g["bias:0"] = np.full(b, np.nan if nan and n == 2 else 0.1, np.float32)
    with open(path, "rb") as f:
        data = f.read()
    os.remove(path)
    put("nbrdf", name, data[:truncate] if truncate else data)


NBRDF = [((6, 21), 21), ((21, 21), 21), ((21, 3), 3)]
nbrdf("valid.h5", NBRDF)
nbrdf("wrong-shape.h5", [((6, 21), 21), ((21, 20), 21), ((21, 3), 3)])
nbrdf("nan-bias.h5", NBRDF, nan=True)
nbrdf("truncated.h5", NBRDF, truncate=3000)

# filters_csv: filter transmission tables (acquire/filters.h) as `specula filters design` writes them, and refusals.
put("filters_csv", "two-filters.csv", "wavelength_nm,a,b\n400,0.1,0.9\n570,0.8,0.2\n740,0.1,0.0\n")
put("filters_csv", "comment-crlf.csv", "# designed\r\nwavelength_nm,f1\r\n420,0\r\n720,1\r\n")
put("filters_csv", "negative.csv", "wavelength_nm,a\n400,0.5\n560,-0.2\n740,0.5\n")
put("filters_csv", "above-one.csv", "wavelength_nm,a\n400,0.5\n740,1.5\n")
put("filters_csv", "short-range.csv", "wavelength_nm,a\n450,0.5\n700,0.5\n")
put("filters_csv", "decreasing.csv", "wavelength_nm,a\n500,0.5\n400,0.5\n")
put("filters_csv", "ragged.csv", "wavelength_nm,a,b\n400,0.5\n740,0.5,0.1,0.3\n")
put("filters_csv", "not-numbers.csv", "wavelength_nm,a\n400,nan\n740,1e999\n")
