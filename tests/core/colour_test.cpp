#include "specula/core/colour.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "quadrature_support.h"
#include "specula/core/error.h"
#include "test_support.h"

namespace specula {
namespace {

Eigen::Vector2d chromaticity(const Eigen::Vector3d& xyz) { return xyz.head<2>() / xyz.sum(); }

double luminance709(const Eigen::Vector3d& rgb) { return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]; }

TEST(Colour, D65WhiteHasTheD65Chromaticity) {
  for (const auto& grid : {WavelengthGrid::range(360, 780, 1), WavelengthGrid::range(380, 780, 5)}) {
    const SpectrumToXyz conv(grid, SpectrumKind::reflectance, illuminant("D65", grid));
    EXPECT_NEAR(conv.white()[1], 1.0, 1e-12);
    const Eigen::Vector2d xy = chromaticity(conv.white());
    EXPECT_NEAR(xy[0], 0.3127, 1e-4) << grid.describe();
    EXPECT_NEAR(xy[1], 0.3290, 1e-4) << grid.describe();
    const Eigen::VectorXd ones = Eigen::VectorXd::Ones(Eigen::Index(grid.size()));
    EXPECT_LT((conv.weights() * ones - conv.white()).norm(), 1e-12);
  }
}

// The CIE 1931 CMFs have equal integrals, so equal energy sits at x = y = 1/3.
TEST(Colour, RadianceFlatSpectrumIsEqualEnergyWhite) {
  const WavelengthGrid grid = WavelengthGrid::range(360, 830, 1);
  const SpectrumToXyz conv(grid, SpectrumKind::radiance, Eigen::VectorXd());
  EXPECT_NEAR(conv.white()[1], 1.0, 1e-12);
  EXPECT_NEAR(chromaticity(conv.white())[0], 1.0 / 3.0, 1e-4);
  EXPECT_NEAR(chromaticity(conv.white())[1], 1.0 / 3.0, 1e-4);
}

// XYZ on an irregular grid (spacings 3 to 20 nm) is the trapezoid rule on the actual band centres, which is the
// direct integral over the 1 nm CMF table within its error bound; a code that assumed a uniform step fails.
TEST(Colour, XyzOnAnIrregularGridIsTheDirectIntegral) {
  const WavelengthGrid grid = test::irregular_grid();
  ASSERT_FALSE(grid.uniform());
  const test::Spectrum s = [](double l) {
    return 0.5 + 0.4 * std::sin((l - 400) / 45) + 0.1 * std::cos((l - 400) / 13);
  };
  const test::Spectrum light = [](double l) { return 1 + 0.8 * (l - 400) / 300 + 0.2 * std::sin(l / 30); };
  Eigen::VectorXd s_grid(Eigen::Index(grid.size())), light_grid(Eigen::Index(grid.size()));
  for (std::size_t i = 0; i < grid.size(); ++i) {
    s_grid[Eigen::Index(i)] = s(grid[i]);
    light_grid[Eigen::Index(i)] = light(grid[i]);
  }
  const auto ratios = [](const std::vector<double>& i) {
    return Eigen::Vector3d(i[0] / i[3], i[1] / i[3], i[2] / i[3]);
  };
  for (const SpectrumKind kind : {SpectrumKind::radiance, SpectrumKind::reflectance}) {
    const test::Spectrum lit = kind == SpectrumKind::radiance ? s : [&](double l) { return s(l) * light(l); };
    const test::Spectrum white = kind == SpectrumKind::radiance ? test::Spectrum([](double) { return 1.0; }) : light;
    std::vector<test::Spectrum> integrands;
    for (int c = 0; c < 3; ++c) integrands.push_back([&, c](double l) { return test::cmf_at(c, l) * lit(l); });
    integrands.push_back([&](double l) { return test::cmf_at(1, l) * white(l); });
    const test::Propagated want = test::propagate(integrands, grid, ratios);
    const SpectrumToXyz conv(grid, kind, light_grid);
    test::expect_integrals(conv.weights() * s_grid, want, 1e-12);
  }
}

TEST(Colour, SpectrumToXyzChecksSizes) {
  const WavelengthGrid grid = WavelengthGrid::range(400, 700, 10);
  EXPECT_THROW(SpectrumToXyz(grid, SpectrumKind::reflectance, Eigen::VectorXd::Ones(30)), UsageError);
  EXPECT_THROW(SpectrumToXyz(WavelengthGrid::range(900, 1000, 10), SpectrumKind::radiance, Eigen::VectorXd()),
               UsageError);
  const SpectrumToXyz conv(grid, SpectrumKind::reflectance, illuminant("D65", grid));
  RowMatrixXf spectra(4, 30);
  RowMatrixX3f xyz(4, 3);
  EXPECT_THROW(conv.apply(spectra, xyz), UsageError);
  RowMatrixXf good = RowMatrixXf::Constant(4, 31, 0.5f);
  RowMatrixX3f short_out(3, 3);
  EXPECT_THROW(conv.apply(good, short_out), UsageError);
}

TEST(Colour, ApplyEqualsTheWeightMatrix) {
  const WavelengthGrid grid = WavelengthGrid::range(400, 700, 10);
  const SpectrumToXyz conv(grid, SpectrumKind::reflectance, illuminant("A", grid));
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  RowMatrixXf spectra(257, 31);
  for (Eigen::Index i = 0; i < spectra.size(); ++i) spectra.data()[i] = u(rng);
  RowMatrixX3f xyz(257, 3);
  conv.apply(spectra, xyz);
  for (Eigen::Index i = 0; i < spectra.rows(); ++i) {
    const Eigen::Vector3d expect = conv.weights() * spectra.row(i).transpose().cast<double>();
    EXPECT_LT((xyz.row(i).transpose().cast<double>() - expect).cwiseAbs().maxCoeff(), 1e-6);
  }
}

// IEC 61966-2-1 publishes the RGB -> XYZ matrix to four decimals; ours is derived from its primaries
// and white point, so it must round to the published one.
TEST(Colour, SrgbMatrixRoundsToThePublishedIecMatrix) {
  Eigen::Matrix3d published;
  published << 0.4124, 0.3576, 0.1805, 0.2126, 0.7152, 0.0722, 0.0193, 0.1192, 0.9505;
  const Eigen::Matrix3d rgb_to_xyz = xyz_to_linear_srgb().inverse();
  EXPECT_LT((rgb_to_xyz - published).cwiseAbs().maxCoeff(), 5e-5 + 1e-12);
  // The white (1, 1, 1) is x = 0.3127, y = 0.3290 at Y = 1.
  const Eigen::Vector3d white = rgb_to_xyz * Eigen::Vector3d::Ones();
  EXPECT_NEAR(white[1], 1.0, 1e-12);
  EXPECT_NEAR(chromaticity(white)[0], 0.3127, 1e-12);
  EXPECT_NEAR(chromaticity(white)[1], 0.3290, 1e-12);
}

TEST(Colour, PerfectReflectorUnderD65IsSrgbWhite) {
  const WavelengthGrid grid = WavelengthGrid::range(380, 780, 5);
  const SpectrumToXyz conv(grid, SpectrumKind::reflectance, illuminant("D65", grid));
  RowMatrixXf spectra = RowMatrixXf::Ones(1, Eigen::Index(grid.size()));
  RowMatrixX3f xyz(1, 3), linear(1, 3);
  conv.apply(spectra, xyz);
  std::array<std::uint8_t, 3> rgb{};
  for (bool adapt : {true, false}) {
    DisplayOptions opt;
    opt.adapt_to_d65 = adapt;
    xyz_to_display(xyz, conv.white(), opt, linear, rgb);
    for (int c = 0; c < 3; ++c) {
      EXPECT_NEAR(linear(0, c), 1.0, 1e-3) << "adapt " << adapt;
      EXPECT_EQ(rgb[std::size_t(c)], 255) << "adapt " << adapt;
    }
  }
}

// Under illuminant A a perfect reflector is still displayed white once adapted, and orange without.
TEST(Colour, AdaptationNeutralisesTheSceneWhite) {
  const WavelengthGrid grid = WavelengthGrid::range(380, 780, 5);
  const SpectrumToXyz conv(grid, SpectrumKind::reflectance, illuminant("A", grid));
  RowMatrixX3f xyz(1, 3);
  xyz.row(0) = (0.5 * conv.white()).cast<float>().transpose();
  RowMatrixX3f linear(1, 3);
  DisplayOptions opt;
  opt.desaturate = false;
  xyz_to_display(xyz, conv.white(), opt, linear, {});
  const Eigen::Matrix3d to_xyz = xyz_to_linear_srgb().inverse();
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(linear(0, c), 0.5 * to_xyz.row(1).sum(), 1e-3);
  opt.adapt_to_d65 = false;
  xyz_to_display(xyz, conv.white(), opt, linear, {});
  EXPECT_GT(linear(0, 0), linear(0, 1));
  EXPECT_GT(linear(0, 1), linear(0, 2));
}

TEST(Colour, ExposureAndReinhard) {
  // Neutral XYZ (D65 white direction) of luminance 0.25 and 3.
  const Eigen::Vector3d white(0.3127 / 0.3290, 1.0, (1 - 0.3127 - 0.3290) / 0.3290);
  RowMatrixX3f xyz(2, 3);
  xyz.row(0) = (0.25 * white).cast<float>().transpose();
  xyz.row(1) = (3.0 * white).cast<float>().transpose();
  RowMatrixX3f linear(2, 3);
  DisplayOptions opt;
  opt.adapt_to_d65 = false;
  opt.exposure_stops = 1.0;
  xyz_to_display(xyz, white, opt, linear, {});
  EXPECT_NEAR(linear(0, 1), 0.5, 1e-6);
  EXPECT_NEAR(linear(1, 1), 1.0, 1e-6);
  opt.exposure_stops = 0.0;
  opt.tone = ToneMap::reinhard;
  xyz_to_display(xyz, white, opt, linear, {});
  EXPECT_NEAR(linear(0, 1), 0.25 / 1.25, 1e-6);
  EXPECT_NEAR(linear(1, 1), 3.0 / 4.0, 1e-6);
}

TEST(Colour, DisplayChecksOutputSizes) {
  RowMatrixX3f xyz = RowMatrixX3f::Zero(4, 3);
  RowMatrixX3f linear(3, 3), none(0, 3);
  std::vector<std::uint8_t> bytes(11);
  EXPECT_THROW(xyz_to_display(xyz, Eigen::Vector3d(0.95, 1, 1.09), {}, linear, {}), UsageError);
  EXPECT_THROW(xyz_to_display(xyz, Eigen::Vector3d(0.95, 1, 1.09), {}, none, bytes), UsageError);
  EXPECT_THROW(xyz_to_display(xyz, Eigen::Vector3d(0, 0, 0), {}, none, {}), UsageError);
  bytes.resize(12, 99);
  xyz_to_display(xyz, Eigen::Vector3d(0.95, 1, 1.09), {}, none, bytes);
  for (std::uint8_t b : bytes) EXPECT_EQ(b, 0);
}

// The 8-bit output equals rounding the sRGB encoding, for every code and at the half-way points.
TEST(Colour, EightBitOutputIsTheRoundedEncoding) {
  const Eigen::Matrix3d to_xyz = xyz_to_linear_srgb().inverse();
  std::vector<double> values;
  for (int k = 0; k <= 255; ++k)
    for (double d : {-0.4999, -0.25, 0.0, 0.25, 0.4999}) {
      const double e = (k + d) / 255.0;
      if (e >= 0 && e <= 1) values.push_back(srgb_decode(e));
    }
  RowMatrixX3f xyz(Eigen::Index(values.size()), 3);
  for (std::size_t i = 0; i < values.size(); ++i)
    xyz.row(Eigen::Index(i)) = (to_xyz * Eigen::Vector3d::Constant(values[i])).cast<float>().transpose();
  RowMatrixX3f linear(xyz.rows(), 3);
  std::vector<std::uint8_t> bytes(3 * values.size());
  DisplayOptions opt;
  opt.adapt_to_d65 = false;
  xyz_to_display(xyz, Eigen::Vector3d(0.95, 1, 1.09), opt, linear, bytes);
  for (std::size_t i = 0; i < values.size(); ++i)
    for (int c = 0; c < 3; ++c) {
      const double v = linear(Eigen::Index(i), c);
      EXPECT_EQ(bytes[3 * i + std::size_t(c)], int(std::lround(srgb_encode(v) * 255.0))) << v;
      EXPECT_NEAR(v, values[i], 1e-5);
    }
}

TEST(Colour, SrgbTransferFunction) {
  EXPECT_EQ(srgb_encode(0.0), 0.0);
  EXPECT_EQ(srgb_encode(1.0), 1.0);
  EXPECT_EQ(srgb_encode(-0.5), 0.0);
  EXPECT_EQ(srgb_encode(2.0), 1.0);
  EXPECT_EQ(srgb_encode(std::nan("")), 0.0);
  // IEC 61966-2-1 breakpoints: linear 0.0031308 <-> encoded 0.04045, slope 12.92 below.
  EXPECT_NEAR(srgb_encode(0.0031308), 0.04045, 1e-6);
  EXPECT_NEAR(srgb_decode(0.04045), 0.0031308, 1e-7);
  EXPECT_NEAR(srgb_encode(0.001), 0.01292, 1e-12);
  EXPECT_NEAR(srgb_encode(0.0031308 * (1 + 1e-9)), srgb_encode(0.0031308 * (1 - 1e-9)), 1e-6);
  // Encoded 0.5 is 21.404 % linear; linear 0.18 (mid grey) is code 118.
  EXPECT_NEAR(srgb_decode(0.5), 0.214041, 1e-6);
  EXPECT_EQ(std::lround(255 * srgb_encode(0.18)), 118);
  for (int i = 0; i <= 1000; ++i) {
    const double v = i / 1000.0;
    EXPECT_NEAR(srgb_encode(srgb_decode(v)), v, 1e-12);
    EXPECT_NEAR(srgb_decode(srgb_encode(v)), v, 1e-12);
  }
}

TEST(Colour, LabOfTheWhiteAndOfMidGrey) {
  const Eigen::Vector3d white(0.95047, 1.0, 1.08883);
  const Eigen::Vector3d lab = xyz_to_lab(white, white);
  EXPECT_NEAR(lab[0], 100.0, 1e-12);
  EXPECT_NEAR(lab[1], 0.0, 1e-12);
  EXPECT_NEAR(lab[2], 0.0, 1e-12);
  EXPECT_NEAR(xyz_to_lab(0.18 * white, white)[0], 116.0 * std::cbrt(0.18) - 16.0, 1e-12);
  // Below the CIE breakpoint (216/24389) L* = (24389/27) Y.
  EXPECT_NEAR(xyz_to_lab(0.001 * white, white)[0], 24389.0 / 27.0 * 0.001, 1e-12);
  EXPECT_NEAR(xyz_to_lab(Eigen::Vector3d::Zero(), white)[0], 0.0, 1e-12);
  EXPECT_THROW(xyz_to_lab(white, Eigen::Vector3d(1, 0, 1)), UsageError);
}

// Sharma, Wu & Dalal (2005), "The CIEDE2000 color-difference formula: implementation notes,
// supplementary test data, and mathematical observations", Table 1: L1 a1 b1 L2 a2 b2 dE00.
constexpr double kSharma[34][7] = {
    {50.0000, 2.6772, -79.7751, 50.0000, 0.0000, -82.7485, 2.0425},
    {50.0000, 3.1571, -77.2803, 50.0000, 0.0000, -82.7485, 2.8615},
    {50.0000, 2.8361, -74.0200, 50.0000, 0.0000, -82.7485, 3.4412},
    {50.0000, -1.3802, -84.2814, 50.0000, 0.0000, -82.7485, 1.0000},
    {50.0000, -1.1848, -84.8006, 50.0000, 0.0000, -82.7485, 1.0000},
    {50.0000, -0.9009, -85.5211, 50.0000, 0.0000, -82.7485, 1.0000},
    {50.0000, 0.0000, 0.0000, 50.0000, -1.0000, 2.0000, 2.3669},
    {50.0000, -1.0000, 2.0000, 50.0000, 0.0000, 0.0000, 2.3669},
    {50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0009, 7.1792},
    {50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0010, 7.1792},
    {50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0011, 7.2195},
    {50.0000, 2.4900, -0.0010, 50.0000, -2.4900, 0.0012, 7.2195},
    {50.0000, -0.0010, 2.4900, 50.0000, 0.0009, -2.4900, 4.8045},
    {50.0000, -0.0010, 2.4900, 50.0000, 0.0010, -2.4900, 4.8045},
    {50.0000, -0.0010, 2.4900, 50.0000, 0.0011, -2.4900, 4.7461},
    {50.0000, 2.5000, 0.0000, 50.0000, 0.0000, -2.5000, 4.3065},
    {50.0000, 2.5000, 0.0000, 73.0000, 25.0000, -18.0000, 27.1492},
    {50.0000, 2.5000, 0.0000, 61.0000, -5.0000, 29.0000, 22.8977},
    {50.0000, 2.5000, 0.0000, 56.0000, -27.0000, -3.0000, 31.9030},
    {50.0000, 2.5000, 0.0000, 58.0000, 24.0000, 15.0000, 19.4535},
    {50.0000, 2.5000, 0.0000, 50.0000, 3.1736, 0.5854, 1.0000},
    {50.0000, 2.5000, 0.0000, 50.0000, 3.2972, 0.0000, 1.0000},
    {50.0000, 2.5000, 0.0000, 50.0000, 1.8634, 0.5757, 1.0000},
    {50.0000, 2.5000, 0.0000, 50.0000, 3.2592, 0.3350, 1.0000},
    {60.2574, -34.0099, 36.2677, 60.4626, -34.1751, 39.4387, 1.2644},
    {63.0109, -31.0961, -5.8663, 62.8187, -29.7946, -4.0864, 1.2630},
    {61.2901, 3.7196, -5.3901, 61.4292, 2.2480, -4.9620, 1.8731},
    {35.0831, -44.1164, 3.7933, 35.0232, -40.0716, 1.5901, 1.8645},
    {22.7233, 20.0904, -46.6940, 23.0331, 14.9730, -42.5619, 2.0373},
    {36.4612, 47.8580, 18.3852, 36.2715, 50.5065, 21.2231, 1.4146},
    {90.8027, -2.0831, 1.4410, 91.1528, -1.6435, 0.0447, 1.4441},
    {90.9257, -0.5406, -0.9208, 88.6381, -0.8985, -0.7239, 1.5381},
    {6.7747, -0.2908, -2.4247, 5.8714, -0.0985, -2.2286, 0.6377},
    {2.0776, 0.0795, -1.1350, 0.9033, -0.0636, -0.5514, 0.9082},
};

TEST(Colour, Ciede2000MatchesSharmaWuDalalTestData) {
  for (int i = 0; i < 34; ++i) {
    const auto& p = kSharma[i];
    const Eigen::Vector3d a(p[0], p[1], p[2]), b(p[3], p[4], p[5]);
    EXPECT_NEAR(ciede2000(a, b), p[6], 1e-4) << "pair " << i + 1;
    EXPECT_NEAR(ciede2000(b, a), p[6], 1e-4) << "pair " << i + 1 << " reversed";
    EXPECT_EQ(ciede2000(a, a), 0.0) << "pair " << i + 1;
  }
}

TEST(Colour, DesaturationKeepsLuminanceAndHueAndLandsInGamut) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.6, 1.8);
  int mapped = 0;
  for (int n = 0; n < 20000; ++n) {
    const Eigen::Vector3d in(u(rng), u(rng), u(rng));
    const double y = luminance709(in);
    const Eigen::Vector3d out = desaturate_into_gamut(in);
    ASSERT_GE(out.minCoeff(), 0.0);
    ASSERT_LE(out.maxCoeff(), 1.0);
    if (y <= 0) {
      EXPECT_EQ(out, Eigen::Vector3d::Zero());
      continue;
    }
    if (y >= 1) {
      EXPECT_EQ(out, Eigen::Vector3d::Ones());
      continue;
    }
    EXPECT_NEAR(luminance709(out), y, 1e-12);
    const Eigen::Vector3d grey = Eigen::Vector3d::Constant(y);
    const Eigen::Vector3d d_in = in - grey, d_out = out - grey;
    EXPECT_LT(d_in.cross(d_out).norm(), 1e-12 * (1 + d_in.norm()));
    EXPECT_GE(d_in.dot(d_out), 0.0);
    if (in.minCoeff() >= 0 && in.maxCoeff() <= 1) {
      EXPECT_EQ(out, in);
    } else {
      ++mapped;
      // Least desaturation: some channel ends on the gamut boundary.
      EXPECT_TRUE(std::abs(out.minCoeff()) < 1e-12 || std::abs(out.maxCoeff() - 1) < 1e-12) << in.transpose();
    }
  }
  EXPECT_GT(mapped, 1000);
  EXPECT_EQ(desaturate_into_gamut(Eigen::Vector3d(std::nan(""), 0.5, 0.5)), Eigen::Vector3d::Zero());
}

TEST(Colour, BradfordOfAWhiteOntoItselfIsIdentity) {
  for (const Eigen::Vector3d& w :
       {Eigen::Vector3d(0.95047, 1.0, 1.08883), Eigen::Vector3d(1.0985, 1.0, 0.35585), Eigen::Vector3d(2.0, 2.0, 2.0)})
    EXPECT_LT((bradford_adaptation(w, w) - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-14);
  const Eigen::Vector3d d50(0.96422, 1.0, 0.82521), d65(0.95047, 1.0, 1.08883);
  EXPECT_LT((bradford_adaptation(d50, d65) * d50 - d65).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_THROW(bradford_adaptation(Eigen::Vector3d(0, 0, 0), d65), UsageError);
}

// Lindbloom's published Bradford matrix from D50 to D65 (whites of the 1931 observer, 5 nm tables).
TEST(Colour, BradfordD50ToD65MatchesThePublishedMatrix) {
  Eigen::Matrix3d published;
  published << 0.9555766, -0.0230393, 0.0631636, -0.0282895, 1.0099416, 0.0210077, 0.0122982, -0.0204830, 1.3299098;
  const Eigen::Matrix3d m =
      bradford_adaptation(Eigen::Vector3d(0.96422, 1.0, 0.82521), Eigen::Vector3d(0.95047, 1.0, 1.08883));
  EXPECT_LT((m - published).cwiseAbs().maxCoeff(), 1e-6);
}

// ColorChecker under D65: Ohta's (1997) reflectances against the sRGB values BabelColor / X-Rite publish.
std::vector<std::vector<double>> read_reflectance_columns(const std::filesystem::path& path,
                                                          std::vector<std::string>& names) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  std::stringstream header(line);
  std::string cell;
  while (std::getline(header, cell, ',')) {
    if (cell.size() >= 2 && cell.front() == '"') cell = cell.substr(1, cell.size() - 2);
    names.push_back(cell);
  }
  std::vector<std::vector<double>> cols(names.size());
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    std::stringstream ss(line);
    for (std::size_t c = 0; std::getline(ss, cell, ',') && c < cols.size(); ++c)
      cols[c].push_back(std::strtod(cell.c_str(), nullptr));
  }
  return cols;
}

TEST(Colour, ColorCheckerUnderD65MatchesPublishedSrgb) {
  SPECULA_REQUIRE_SHARED();
  std::vector<std::string> names;
  const auto cols = read_reflectance_columns(
      test::shared_dir() / "data" / "reflectance" / "colorchecker24_ohta1997_reflectance.csv", names);
  ASSERT_EQ(names.size(), 25u);
  const WavelengthGrid grid(cols[0]);
  ASSERT_TRUE(grid.approx_equal(WavelengthGrid::range(380, 780, 5)));
  const SpectrumToXyz conv(grid, SpectrumKind::reflectance, illuminant("D65", grid));

  // BabelColor's values average many charts, Ohta measured one, so exact agreement is not expected.
  // Measured: white (242,242,240), 2 counts and dE00 0.45; red (178,47,58), 7 counts in green (a dark
  // channel, where one count is a small colour step) and dE00 1.15, about one just-noticeable difference.
  struct Patch {
    const char* name;
    int r, g, b;
    int max_counts;
    double max_de2000;
  };
  const Patch patches[] = {{"white 9.5 (.05 D)", 243, 243, 242, 3, 1.0}, {"red", 175, 54, 60, 8, 2.0}};
  for (const Patch& p : patches) {
    const auto it = std::find(names.begin(), names.end(), p.name);
    ASSERT_NE(it, names.end()) << p.name;
    const auto& refl = cols[std::size_t(it - names.begin())];
    RowMatrixXf spectrum(1, Eigen::Index(grid.size()));
    for (std::size_t i = 0; i < grid.size(); ++i) spectrum(0, Eigen::Index(i)) = float(refl[i]);
    RowMatrixX3f xyz(1, 3), linear(1, 3);
    conv.apply(spectrum, xyz);
    std::array<std::uint8_t, 3> rgb{};
    xyz_to_display(xyz, conv.white(), DisplayOptions{}, linear, rgb);
    const int published[3] = {p.r, p.g, p.b};
    int worst = 0;
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(int(rgb[std::size_t(c)]) - published[c]));
    RecordProperty(std::string(p.name) + " sRGB8",
                   std::to_string(rgb[0]) + "," + std::to_string(rgb[1]) + "," + std::to_string(rgb[2]));
    EXPECT_LE(worst, p.max_counts) << p.name << ": got " << int(rgb[0]) << "," << int(rgb[1]) << "," << int(rgb[2]);

    // The same comparison in CIELAB (D65 white): published sRGB -> XYZ against the patch's XYZ.
    const Eigen::Matrix3d to_xyz = xyz_to_linear_srgb().inverse();
    const Eigen::Vector3d pub_xyz =
        to_xyz * Eigen::Vector3d(srgb_decode(p.r / 255.0), srgb_decode(p.g / 255.0), srgb_decode(p.b / 255.0));
    const Eigen::Vector3d white = to_xyz * Eigen::Vector3d::Ones();
    const Eigen::Vector3d ours = to_xyz * linear.row(0).transpose().cast<double>();
    const double de = ciede2000(xyz_to_lab(ours, white), xyz_to_lab(pub_xyz, white));
    RecordProperty(std::string(p.name) + " dE2000", std::to_string(de));
    EXPECT_LT(de, p.max_de2000) << p.name;
  }
}

}  // namespace
}  // namespace specula
