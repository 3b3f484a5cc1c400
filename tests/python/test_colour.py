"""Spectra -> XYZ -> sRGB against direct integration of the CIE tables and sRGB's published values."""
import numpy as np
import pytest

import specula

NM = np.arange(380.0, 781.0, 5.0)


def test_cmf_and_illuminant_tables_hold_published_values():
    c = specula.cmf([450.0, 555.0, 600.0])
    np.testing.assert_allclose(c[1, 1], 1.0, atol=1e-4)       # ybar(555) = 1.0000
    np.testing.assert_allclose(c[2, 0], 1.0622, atol=1e-4)    # xbar(600)
    np.testing.assert_allclose(c[0, 2], 1.7721, atol=1e-3)    # zbar(450)
    np.testing.assert_allclose(specula.illuminant("D65", [560.0]), [100.0], atol=1e-3)


def test_xyz_is_the_trapezoid_integral_of_the_cmfs():
    rng = np.random.default_rng(2)
    r = rng.uniform(0, 1, (7, 5, NM.size))
    cmf = specula.cmf(NM)
    ill = specula.illuminant("D65", NM)
    k = 1 / np.trapz(cmf[:, 1] * ill, NM)
    expected = k * np.trapz(cmf[None, None] * (ill[:, None] * r[..., None]), NM, axis=2)
    xyz = specula.spectra_to_xyz(r, NM)
    assert xyz.shape == (7, 5, 3)
    np.testing.assert_allclose(xyz, expected, rtol=1e-12)
    w, white = specula.xyz_weights(NM)
    np.testing.assert_allclose(white, [0.95047, 1.0, 1.08883], atol=2e-3)  # D65 white, Y = 1
    np.testing.assert_allclose(specula.spectra_to_xyz(np.ones(NM.size), NM), white, rtol=1e-12)
    rad = specula.spectra_to_xyz(np.ones(NM.size), NM, kind="radiance")
    np.testing.assert_allclose(rad[1], 1.0, rtol=1e-12)
    a = specula.spectra_to_xyz(r[0, 0], NM, illuminant="A")
    ia = specula.illuminant("A", NM)
    np.testing.assert_allclose(a, np.trapz(cmf * (ia * r[0, 0])[:, None], NM, axis=0) / np.trapz(cmf[:, 1] * ia, NM),
                               rtol=1e-12)
    custom = specula.spectra_to_xyz(r[0, 0], NM, illuminant=ill * 3)
    np.testing.assert_allclose(custom, xyz[0, 0], rtol=1e-12)


SRGB_FROM_XYZ = np.array([[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]])


def encode(linear):
    return np.where(linear <= 0.0031308, 12.92 * linear, 1.055 * np.power(linear, 1 / 2.4) - 0.055)


def test_srgb_of_known_colours():
    white = np.array([0.95047, 1.0, 1.08883])
    red = np.array([0.4124, 0.2126, 0.0193])
    srgb, linear = specula.xyz_to_srgb(np.stack([white, red]), white=white)
    np.testing.assert_array_equal(srgb[0], [255, 255, 255])
    np.testing.assert_array_equal(srgb[1], [255, 0, 0])
    np.testing.assert_allclose(linear[1], [1, 0, 0], atol=2e-3)
    # In-gamut colours: IEC 61966-2-1's matrix and transfer function, to one 8-bit step.
    rng = np.random.default_rng(4)
    lin = rng.uniform(0.02, 0.98, (200, 3))
    xyz = lin @ np.linalg.inv(SRGB_FROM_XYZ).T
    srgb, linear = specula.xyz_to_srgb(xyz, white=white)
    np.testing.assert_allclose(linear, lin, atol=2e-3)
    assert np.abs(srgb.astype(int) - np.round(255 * encode(lin))).max() <= 1
    half, _ = specula.xyz_to_srgb(white, white=white, exposure=-1)  # 2^-1: linear 0.5 -> 0.7354 encoded
    assert np.abs(half.astype(int) - 255 * 0.7354).max() <= 1
    img = np.full((4, 6, NM.size), 1.0)
    s, _ = specula.spectra_to_srgb(img, NM)
    assert s.shape == (4, 6, 3) and s.dtype == np.uint8
    assert np.all(s == 255)


def test_colour_errors():
    with pytest.raises(specula.UsageError, match="kind 'light'"):
        specula.spectra_to_xyz(np.ones(NM.size), NM, kind="light")
    with pytest.raises(specula.UsageError, match="last axis"):
        specula.spectra_to_xyz(np.ones(3), NM)
    with pytest.raises(specula.UsageError):
        specula.spectra_to_xyz(np.ones(NM.size), NM, illuminant="F2")
    with pytest.raises(specula.InputError):
        specula.spectra_to_xyz(np.ones(3), [500.0, 400.0, 600.0])


def test_illuminants_are_named_as_on_the_command_line(tmp_path):
    # blackbody:K is Planck's law normalised to 1 at 560 nm, computed here independently.
    h, c, k = 6.62607015e-34, 2.99792458e8, 1.380649e-23
    def planck(nm, t):
        lam = np.asarray(nm) * 1e-9
        return 1.0 / (lam ** 5 * np.expm1(h * c / (lam * k * t)))
    got = specula.illuminant("blackbody:3000", NM)
    np.testing.assert_allclose(got, planck(NM, 3000) / planck(560.0, 3000), rtol=1e-6)
    # An SPD file, as `specula render --illuminant spd.csv` reads it, resampled to the wavelengths.
    spd = tmp_path / "spd.csv"
    spd.write_text("wavelength_nm,value\n" + "".join(f"{w},{2 * w}\n" for w in range(380, 781, 20)))
    np.testing.assert_allclose(specula.illuminant(str(spd), NM), 2 * NM, rtol=1e-9)
    with pytest.raises(specula.UsageError, match="illuminant 'D20'"):
        specula.illuminant("D20", NM)
