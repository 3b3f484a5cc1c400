#include "specula/codec/environment.h"

#include <gtest/gtest.h>
#include <omp.h>

#include <Eigen/Cholesky>

#include <cmath>
#include <fstream>
#include <numbers>

#include "grid_fixture.h"
#include "quadrature_support.h"
#include "specula/codec/diff.h"
#include "specula/codec/spectral_grid.h"
#include "specula/core/brdf_models.h"
#include "specula/core/colour.h"
#include "specula/core/error.h"
#include "specula/store/io/exr.h"
#include "test_support.h"

namespace specula::codec {
namespace {

using std::numbers::pi;
constexpr std::size_t N = brdf::kMerlCells;
const WavelengthGrid& kGrid = test::kCodecBands;
using test::grid_of;

Eigen::Vector3d xyz_at(const SphereRenders& r, std::size_t g, std::size_t p) {
  return {r.xyz[g][3 * p], r.xyz[g][3 * p + 1], r.xyz[g][3 * p + 2]};
}

Eigen::Vector3d normal_of(std::size_t size, std::size_t p) {
  const double x = 2 * (double(p % size) + 0.5) / double(size) - 1, y = 1 - 2 * (double(p / size) + 0.5) / double(size);
  return {x, y, std::sqrt(std::max(0.0, 1 - x * x - y * y))};
}

Eigen::Matrix<double, 3, Eigen::Dynamic> cmf_weights(const WavelengthGrid& grid) {
  return SpectrumToXyz(grid, SpectrumKind::radiance, Eigen::VectorXd::Ones(Eigen::Index(grid.size()))).weights();
}

// A map that is black except the 2 x 2 pixels around direction (theta, phi), and no sun.
Environment spot(double theta, double phi, double radiance) {
  Environment e;
  e.wavelengths = kGrid;
  e.width = 64;
  e.height = 32;
  e.sun_irradiance.resize(0);
  e.radiance.assign(e.width * e.height * kGrid.size(), 0.0f);
  const auto cy = std::size_t(std::lround(theta / pi * 32)), cx = std::size_t(std::lround(phi / (2 * pi) * 64));
  for (std::size_t y = cy - 1; y <= cy; ++y)
    for (std::size_t x = cx - 1; x <= cx; ++x)
      for (std::size_t k = 0; k < kGrid.size(); ++k) e.radiance[(y * 64 + x % 64) * kGrid.size() + k] = float(radiance);
  return e;
}

// A Lambertian albedo rho under uniform radiance L reflects rho L: the integral of cos over the hemisphere is pi.
// The regions (64 x 32) each count with their exact mean cosine n . m, so the only quadrature error comes from
// regions cut by the pixel's horizon, counted whole or not at all: every point of such a region lies within its
// angular diameter D of the horizon (D = acos(cos^2 5.625 deg) = 7.95 deg for an equatorial region), so the
// error is at most the integral of |cos| over the band |cos| < sin D, 2 pi sin^2 D, relative 2 sin^2 D = 3.8 %.
// The viewer-facing pixel of an odd-sized sphere has the meridian phi = pi/2, 3pi/2 as horizon, a region
// boundary, so it is exact (no region direction lies within 2.8 degrees of its horizon, where cells lack data).
TEST(Environment, ALambertianSphereUnderUniformLightShowsRhoTimesL) {
  const Eigen::VectorXd rho = Eigen::VectorXd::LinSpaced(7, 0.2, 0.8), l = Eigen::VectorXd::LinSpaced(7, 1.0, 2.0);
  const store::Grid g = grid_of(brdf::Lambertian(kGrid, rho));
  const std::size_t size = 65;
  const SphereRenders r = render_spheres({&g}, uniform_environment(kGrid, l), size);
  const Eigen::Vector3d expect = cmf_weights(kGrid) * rho.cwiseProduct(l);
  const double bound = 2 * std::pow(std::sin(std::acos(std::pow(std::cos(5.625 * pi / 180), 2))), 2);
  std::size_t checked = 0;
  double worst = 0;
  for (std::size_t p = 0; p < size * size; ++p) {
    if (!r.covered[p] || normal_of(size, p).z() < 0.3) continue;  // at grazing view most cells hold no data
    for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(xyz_at(r, 0, p)[c] / expect[c] - 1));
    ++checked;
  }
  EXPECT_GT(checked, 2500u);
  EXPECT_LT(worst, bound);
  const std::size_t centre = size * size / 2;
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(xyz_at(r, 0, centre)[c], expect[c], 1e-6 * expect[c]);
  // The white (albedo 1 facing the viewer) has no cut region either: exactly L.
  const Eigen::Vector3d white = cmf_weights(kGrid) * l;
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(r.white[c], white[c], 1e-6 * white[c]);
}

// White furnace: an energy-conserving BRDF (Ward, rho_d + rho_s < 1) under uniform radiance reflects its
// directional albedo, at most 1, so no pixel is brighter than the white; with nothing absorbed beyond the
// albedo, a Lambertian of albedo 1 is the white wherever it faces.
TEST(Environment, WhiteFurnace) {
  const Environment env = uniform_environment(kGrid, Eigen::VectorXd::Ones(7));
  const store::Grid ward = grid_of(brdf::Ward(kGrid, Eigen::VectorXd::Constant(7, 0.5),
                                              Eigen::VectorXd::Constant(7, 0.3), Eigen::VectorXd::Constant(7, 0.2)));
  const store::Grid white = grid_of(brdf::Lambertian(kGrid, Eigen::VectorXd::Ones(7)));
  const SphereRenders r = render_spheres({&ward, &white}, env, 33);
  const double bound = 2 * std::pow(std::sin(std::acos(std::pow(std::cos(5.625 * pi / 180), 2))), 2);
  for (std::size_t p = 0; p < 33 * 33; ++p) {
    if (!r.covered[p]) continue;
    EXPECT_LE(xyz_at(r, 0, p).y(), r.white.y() * (1 + bound)) << p;
    EXPECT_LE(xyz_at(r, 1, p).y(), r.white.y() * (1 + bound)) << p;
    if (normal_of(33, p).z() > 0.3) {
      EXPECT_GT(xyz_at(r, 1, p).y(), r.white.y() * (1 - bound)) << p;
    }
  }
}

// Only the sun: a point light, no quadrature, so a Lambertian follows the cosine law exactly,
// rho / pi * E * max(0, n . s), and the white is E (n . s) / pi at the viewer-facing normal.
TEST(Environment, ASunAloneFollowsTheCosineLaw) {
  Environment env = uniform_environment(kGrid, Eigen::VectorXd::Zero(7));
  env.sun_direction = Eigen::Vector3d(0.3, 0.5, 0.8).normalized();
  env.sun_irradiance = Eigen::VectorXd::LinSpaced(7, 2.0, 1.0);
  const Eigen::VectorXd rho = Eigen::VectorXd::LinSpaced(7, 0.7, 0.1);
  const store::Grid g = grid_of(brdf::Lambertian(kGrid, rho));
  const std::size_t size = 40;
  const SphereRenders r = render_spheres({&g}, env, size);
  const Eigen::Vector3d unit = cmf_weights(kGrid) * rho.cwiseProduct(env.sun_irradiance) / pi;
  std::size_t checked = 0;
  for (std::size_t p = 0; p < size * size; ++p) {
    if (!r.covered[p]) continue;
    const Eigen::Vector3d n = normal_of(size, p);
    const double c = n.dot(env.sun_direction);
    if (c <= 0) {
      EXPECT_EQ(xyz_at(r, 0, p).norm(), 0.0) << p;
      continue;
    }
    if (c < 0.1 || n.z() < 0.1) continue;  // near grazing the cells hold no data
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(xyz_at(r, 0, p)[k], unit[k] * c, 1e-5 * unit[k]) << p;
    ++checked;
  }
  EXPECT_GT(checked, 500u);
  const Eigen::Vector3d white = cmf_weights(kGrid) * env.sun_irradiance * env.sun_direction.z() / pi;
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(r.white[k], white[k], 1e-9 * white[k]);
}

// The documented frame: row 0 looks up (+y), phi = 0 is +z (towards the viewer), phi = pi/2 is +x.
TEST(Environment, LatLongDirectionsFollowTheDocumentedFrame) {
  const store::Grid g = grid_of(brdf::Lambertian(kGrid, Eigen::VectorXd::Constant(7, 0.5)));
  const std::size_t size = 32;
  struct Case {
    double theta, phi;
    Eigen::Vector3d dir;
  };
  for (const Case& c : {Case{pi / 2, pi / 2, {1, 0, 0}}, Case{pi / 2, 3 * pi / 2, {-1, 0, 0}},
                        Case{pi / 4, pi, {0, 0.7071, -0.7071}}, Case{pi / 4, 2 * pi, {0, 0.7071, 0.7071}}}) {
    const SphereRenders r = render_spheres({&g}, spot(c.theta, c.phi, 10), size);
    std::size_t best = 0;
    for (std::size_t p = 0; p < size * size; ++p)
      if (r.xyz[0][3 * p + 1] > r.xyz[0][3 * best + 1]) best = p;
    const Eigen::Vector3d n = normal_of(size, best);
    if (c.dir.z() >= 0.5) {  // the light faces the viewer: the brightest normal points at it
      EXPECT_GT(n.dot(c.dir.normalized()), 0.97) << c.theta << " " << c.phi;
    } else {  // behind or beside: the brightest pixel lies on the rim on the light's side
      EXPECT_GT(n.head<2>().normalized().dot(c.dir.head<2>().normalized()), 0.9) << c.theta << " " << c.phi;
    }
    // The half of the sphere facing away is dark.
    for (std::size_t p = 0; p < size * size; ++p)
      if (r.covered[p] && normal_of(size, p).dot(c.dir.normalized()) < -0.2) {
        EXPECT_EQ(r.xyz[0][3 * p + 1], 0.0f);
      }
  }
}

// Cells without data (negative) count as 0; a grid of no data renders black.
TEST(Environment, CellsWithoutDataAreBlack) {
  store::Grid g;
  g.wavelengths = kGrid;
  g.brdf.assign(7 * N, -1.0f);
  const SphereRenders r = render_spheres({&g}, default_environment(kGrid), 16);
  for (const float v : r.xyz[0]) EXPECT_EQ(v, 0.0f);
  EXPECT_GT(r.white.y(), 0);
}

TEST(Environment, RenderingDoesNotDependOnTheThreadCount) {
  const store::Grid g = grid_of(brdf::Ward(kGrid, Eigen::VectorXd::LinSpaced(7, 0.05, 0.4),
                                           Eigen::VectorXd::Constant(7, 0.2), Eigen::VectorXd::Constant(7, 0.1)));
  const Environment env = default_environment(kGrid);
  const int threads = omp_get_max_threads();
  omp_set_num_threads(1);
  const SphereRenders one = render_spheres({&g}, env, 40);
  omp_set_num_threads(3);
  const SphereRenders three = render_spheres({&g}, env, 40);
  omp_set_num_threads(threads);
  EXPECT_EQ(one.xyz[0], three.xyz[0]);
  EXPECT_EQ(one.white, three.white);
}

// The built-in environment is spectrally non-trivial: two greys metameric under equal-energy light (same XYZ)
// render alike under a uniform equal-energy environment and visibly apart under the default one.
TEST(Environment, TheDefaultEnvironmentRevealsMetamers) {
  const WavelengthGrid grid = WavelengthGrid::range(400, 700, 10);
  const auto w = cmf_weights(grid);
  const Eigen::VectorXd flat = Eigen::VectorXd::Constant(31, 0.4);
  // A spectral bump pattern with no XYZ (projected off the CMFs' row space).
  Eigen::VectorXd v(31);
  for (Eigen::Index k = 0; k < 31; ++k) v[k] = std::sin(double(k) * 0.45);
  v -= w.transpose() * (w * w.transpose()).ldlt().solve(w * v);
  const Eigen::VectorXd meta = flat + 0.35 / v.cwiseAbs().maxCoeff() * v;
  ASSERT_GE(meta.minCoeff(), 0.0);
  ASSERT_LT((w * meta - w * flat).norm(), 1e-9 * (w * flat).norm());
  const store::Grid a = grid_of(brdf::Lambertian(grid, flat)), b = grid_of(brdf::Lambertian(grid, meta));
  const GridDiff under_e = diff_grids(a, b, uniform_environment(grid, Eigen::VectorXd::Ones(31)), {.size = 24});
  const GridDiff under_default = diff_grids(a, b, default_environment(grid), {.size = 24});
  EXPECT_LT(under_e.de00_max, 1e-3);
  EXPECT_GT(under_default.de00_mean, 1.0);
}

// An RGB map: every pixel uplifted (non-negative, equal-energy white), so the map's RGB comes back from its
// spectra to 1e-6 where the colour is feasible; a larger map is box-filtered by 2 with exact solid-angle
// weights, and the RGB of each filtered pixel is the same weighted mean of the input's (projection is linear).
TEST(Environment, AnRgbExrIsUpliftedPerPixelAndGivesItsRgbBack) {
  test::ScratchDir dir;
  const WavelengthGrid grid = WavelengthGrid::range(420, 720, 10);
  const auto weights = rgb_weights(grid, Eigen::VectorXd::Ones(31));
  for (const std::size_t w : {std::size_t(64), std::size_t(512)}) {
    const std::size_t h = w / 2;
    std::vector<float> rgb;
    for (std::size_t p = 0; p < w * h; ++p)
      for (const float v : {0.3f + 0.2f * float(p % w) / float(w), 0.5f, 0.2f + 0.3f * float(p / w) / float(h)})
        rgb.push_back(v);
    const auto path = dir / ("env" + std::to_string(w) + ".exr");
    store::write_exr_rgb(path, w, h, rgb);
    std::size_t sw = 0, sh = 0;
    const std::vector<float> stored = store::read_exr_rgb(path, sw, sh);  // half floats as written
    const Environment e = read_environment(path, grid);
    const std::size_t f = w == 64 ? 1 : 2;
    ASSERT_EQ(e.width, w / f);
    ASSERT_EQ(e.height, h / f);
    EXPECT_EQ(e.sun_irradiance.size(), 0);
    double worst = 0;
    for (std::size_t oy = 0; oy < e.height; ++oy)
      for (std::size_t ox = 0; ox < e.width; ++ox) {
        Eigen::Vector3d expect = Eigen::Vector3d::Zero();
        double omega = 0;
        for (std::size_t y = oy * f; y < oy * f + f; ++y) {
          const double o = std::cos(pi * double(y) / double(h)) - std::cos(pi * double(y + 1) / double(h));
          for (std::size_t x = ox * f; x < ox * f + f; ++x) {
            for (int c = 0; c < 3; ++c) expect[c] += o * stored[3 * (y * w + x) + std::size_t(c)];
            omega += o;
          }
        }
        expect /= omega;
        const Eigen::Map<const Eigen::VectorXf> s(e.radiance.data() + (oy * e.width + ox) * 31, 31);
        ASSERT_GE(s.minCoeff(), 0.0f);
        worst = std::max(worst, (weights * s.cast<double>() - expect).cwiseAbs().maxCoeff());
      }
    EXPECT_LT(worst, 1e-6) << w;
  }
}

// A spectral EXR of emission keeps its size and is interpolated onto the grid: linear spectra exactly.
TEST(Environment, ASpectralExrIsInterpolatedOntoTheGrid) {
  test::ScratchDir dir;
  store::Cube cube;
  cube.wavelengths = WavelengthGrid::range(400, 720, 20);
  cube.resize(6, 12, cube.wavelengths.size());
  cube.units = "radiance";
  for (std::size_t p = 0; p < 72; ++p)
    for (std::size_t k = 0; k < cube.bands; ++k)
      cube.data[p * cube.bands + k] = float(0.5 + 0.01 * double(p) + 0.002 * (cube.wavelengths[k] - 400));
  store::write_spectral_exr(dir / "s.exr", cube);
  const Environment e = read_environment(dir / "s.exr", kGrid);
  ASSERT_EQ(e.width, 12u);
  ASSERT_EQ(e.height, 6u);
  for (std::size_t p = 0; p < 72; ++p)
    for (std::size_t k = 0; k < 7; ++k)
      EXPECT_NEAR(e.radiance[p * 7 + k], 0.5 + 0.01 * double(p) + 0.002 * (kGrid[k] - 400), 1e-5);
  // Bands the file does not cover are refused, naming it.
  EXPECT_NE(test::input_error_text([&] {
              read_environment(dir / "s.exr", WavelengthGrid::range(380, 700, 10));
            }).find("s.exr"),
            std::string::npos);
  // Reflectance is not light.
  cube.units = "reflectance";
  store::write_spectral_exr(dir / "t.exr", cube);
  EXPECT_NE(test::input_error_text([&] { read_environment(dir / "t.exr", kGrid); }).find("emission"),
            std::string::npos);
  // A NaN or a negative value, named by file, pixel and wavelength.
  cube.units = "radiance";
  cube.data[(2 * 12 + 5) * cube.bands + 3] = std::nanf("");
  store::write_spectral_exr(dir / "nan.exr", cube);
  const std::string nan = test::input_error_text([&] { read_environment(dir / "nan.exr", kGrid); });
  EXPECT_NE(nan.find("nan.exr: pixel (5, 2) at 460 nm"), std::string::npos) << nan;
  cube.data[(2 * 12 + 5) * cube.bands + 3] = -0.5f;
  store::write_spectral_exr(dir / "neg.exr", cube);
  EXPECT_NE(test::input_error_text([&] { read_environment(dir / "neg.exr", kGrid); }).find("neg.exr"),
            std::string::npos);
}

TEST(Environment, BadEnvironmentFilesAreRefusedNamingTheFile) {
  test::ScratchDir dir;
  std::vector<float> rgb(3 * 8 * 4, 0.5f);
  rgb[3 * (2 * 8 + 1) + 2] = -1;
  store::write_exr_rgb(dir / "neg.exr", 8, 4, rgb);
  const std::string neg = test::input_error_text([&] { read_environment(dir / "neg.exr", kGrid); });
  EXPECT_NE(neg.find("neg.exr: pixel (1, 2) has B = -1"), std::string::npos) << neg;
  rgb[3 * (2 * 8 + 1) + 2] = INFINITY;
  store::write_exr_rgb(dir / "inf.exr", 8, 4, rgb);
  EXPECT_NE(test::input_error_text([&] { read_environment(dir / "inf.exr", kGrid); }).find("inf.exr"),
            std::string::npos);
  EXPECT_THROW(read_environment(dir / "missing.exr", kGrid), InputError);
  // Not an EXR at all, and an EXR cut short.
  { std::ofstream(dir / "junk.exr", std::ios::binary) << "this is not an OpenEXR file at all"; }
  rgb[3 * (2 * 8 + 1) + 2] = 0.5f;
  store::write_exr_rgb(dir / "good.exr", 8, 4, rgb);
  const std::string good = test::read_bytes(dir / "good.exr");
  { std::ofstream(dir / "short.exr", std::ios::binary) << good.substr(0, good.size() / 2); }
  for (const char* name : {"junk.exr", "short.exr"}) {
    try {
      read_environment(dir / name, kGrid);
      ADD_FAILURE() << name << " was accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
  EXPECT_THROW(uniform_environment(kGrid, Eigen::VectorXd::Ones(3)), UsageError);
  EXPECT_THROW(uniform_environment(kGrid, -Eigen::VectorXd::Ones(7)), UsageError);
}

TEST(Environment, MismatchedGridsAndBadSizesAreRefused) {
  const store::Grid g =
      grid_of(brdf::Lambertian(WavelengthGrid::range(400, 700, 50), Eigen::VectorXd::Constant(7, 0.5)));
  const std::string text = test::input_error_text([&] { render_spheres({&g}, default_environment(kGrid), 32); });
  EXPECT_NE(text.find("400-700"), std::string::npos) << text;
  EXPECT_NE(text.find("420-720"), std::string::npos) << text;
  const store::Grid ok = grid_of(brdf::Lambertian(kGrid, Eigen::VectorXd::Constant(7, 0.5)));
  EXPECT_THROW(render_spheres({&ok}, default_environment(kGrid), 4), UsageError);
  EXPECT_THROW(render_spheres({&ok}, default_environment(kGrid), 5000), UsageError);
}

// render_spheres on an irregular grid (spacings 3 to 20 nm): a Lambertian sphere of albedo rho under a uniform sky
// of radiance L shows, at the pixel facing the viewer, XYZ / Y_white = integral of cmf rho L / integral of ybar L
// and the white integral of cmf L / integral of ybar L: by the trapezoid rule on the actual band centres, within its
// error bound of the integrals over every nm of the CMF table.
TEST(Environment, OnAnIrregularGridTheRenderIsTheDirectIntegral) {
  const WavelengthGrid grid = test::irregular_grid();
  const std::size_t b = grid.size();
  const test::Spectrum rho = [](double l) { return 0.5 + 0.35 * std::sin((l - 430) / 50); };
  const test::Spectrum sky = [](double l) { return 1.5 - (l - 400) / 400 + 0.1 * std::cos(l / 20); };
  Eigen::VectorXd rho_g(static_cast<Eigen::Index>(b)), sky_g(static_cast<Eigen::Index>(b));
  for (std::size_t i = 0; i < b; ++i) {
    rho_g[Eigen::Index(i)] = rho(grid[i]);
    sky_g[Eigen::Index(i)] = sky(grid[i]);
  }
  const store::Grid g = grid_of(brdf::Lambertian(grid, rho_g));
  const std::size_t size = 9, centre = 4 * size + 4;  // the pixel centre at x = y = 0: normal +z, as the white's
  const SphereRenders r = render_spheres({&g}, uniform_environment(grid, sky_g), size);
  ASSERT_TRUE(r.covered[centre]);
  Eigen::VectorXd got(6);
  for (std::size_t c = 0; c < 3; ++c) {
    got[Eigen::Index(c)] = r.xyz[0][3 * centre + c] / r.white.y();
    got[Eigen::Index(3 + c)] = r.white[Eigen::Index(c)] / r.white.y();
  }

  std::vector<test::Spectrum> f;
  for (int c = 0; c < 3; ++c) f.push_back([&, c](double l) { return test::cmf_at(c, l) * rho(l) * sky(l); });
  for (int c = 0; c < 3; ++c) f.push_back([&, c](double l) { return test::cmf_at(c, l) * sky(l); });
  const test::Propagated want = test::propagate(f, grid, [](const std::vector<double>& i) {
    Eigen::VectorXd out(6);
    for (int k = 0; k < 6; ++k) out[k] = i[std::size_t(k)] / i[4];
    return out;
  });
  test::expect_integrals(got, want, 1e-5);
}

}  // namespace
}  // namespace specula::codec
