#include "specula/codec/merl.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <random>

#include "specula/core/error.h"
#include "test_support.h"

namespace specula::codec {
namespace {

using std::numbers::pi;
constexpr double kDeg = pi / 180;
constexpr std::size_t N = brdf::kMerlCells;

MerlBrdf random_merl(unsigned seed) {
  MerlBrdf b;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-0.2, 5000.0);
  for (double& v : b.raw) v = u(rng);
  b.raw[7] = -1.0;
  b.raw[8] = 0.0;
  b.raw[9] = 4.9406564584124654e-324;  // a denormal survives bit for bit
  return b;
}

void truncate_to(const std::filesystem::path& p, std::uintmax_t size) { std::filesystem::resize_file(p, size); }

TEST(Merl, FileLayoutIsMerls) {
  test::ScratchDir dir;
  MerlBrdf b;
  for (std::size_t i = 0; i < 3 * N; ++i) b.raw[i] = double(i % 1000) + 0.25;
  const auto p = dir / "a.binary";
  write_merl(p, b);
  const std::string bytes = test::read_bytes(p);
  ASSERT_EQ(bytes.size(), 34992012u);  // 12 + 3 * 90 * 90 * 180 * 8
  std::int32_t dims[3];
  std::memcpy(dims, bytes.data(), 12);
  EXPECT_EQ(dims[0], 90);
  EXPECT_EQ(dims[1], 90);
  EXPECT_EQ(dims[2], 180);
  for (std::size_t i : {std::size_t(0), N - 1, N, 2 * N + 12345, 3 * N - 1}) {
    double v;
    std::memcpy(&v, bytes.data() + 12 + 8 * i, 8);
    EXPECT_EQ(v, double(i % 1000) + 0.25) << i;
  }
}

TEST(Merl, RoundTripIsBitExact) {
  test::ScratchDir dir;
  const MerlBrdf b = random_merl(5);
  write_merl(dir / "a.binary", b);
  const MerlBrdf r = read_merl(dir / "a.binary");
  ASSERT_EQ(std::memcmp(r.raw.data(), b.raw.data(), b.raw.size() * 8), 0);
  write_merl(dir / "b.binary", r);
  EXPECT_EQ(test::read_bytes(dir / "a.binary"), test::read_bytes(dir / "b.binary"));
  EXPECT_EQ(std::distance(std::filesystem::directory_iterator(dir.path()), std::filesystem::directory_iterator()), 2);
}

// Stored values are the cell index (red), twice it (green), minus one (blue, no data in cell 0): a lookup
// returns them times the published scales, at cells worked out by hand from BRDFRead.cpp.
TEST(Merl, LookupUsesTheReferenceConventions) {
  MerlBrdf b;
  for (std::size_t i = 0; i < N; ++i) {
    b.raw[i] = double(i);
    b.raw[N + i] = 2.0 * double(i);
    b.raw[2 * N + i] = double(i) - 1;
  }
  // Normal incidence, theta_o = 61 deg: theta_h = theta_d = 30.5 deg, phi_d = 180 deg.
  // theta_h index floor(90 sqrt(30.5 / 90)) = 52, theta_d index 30, phi_d index 179 (clamped).
  const std::size_t i1 = 179 + 180 * (30 + 90 * 52);
  const Eigen::Vector3d v1 = b.lookup(brdf::StdAngles{0, 0, 61 * kDeg, 0.3});
  EXPECT_DOUBLE_EQ(v1[0], double(i1) / 1500);
  EXPECT_DOUBLE_EQ(v1[1], 2.0 * double(i1) * 1.15 / 1500);
  EXPECT_DOUBLE_EQ(v1[2], (double(i1) - 1) * 1.66 / 1500);
  // theta_h 20 deg, theta_d 40.3 deg, phi_d 50.2 deg (phi_h 10 deg): indices 42, 40, 50.
  const brdf::StdAngles a = brdf::std_angles({20 * kDeg, 10 * kDeg, 40.3 * kDeg, 50.2 * kDeg});
  const std::size_t i2 = 50 + 180 * (40 + 90 * 42);
  EXPECT_DOUBLE_EQ(b.lookup(a)[0], double(i2) / 1500);
  // Reciprocity: swapping the directions reads the same cell.
  EXPECT_DOUBLE_EQ(b.lookup({a.theta_o, a.phi_o, a.theta_i, a.phi_i})[0], double(i2) / 1500);
  EXPECT_THROW(b.lookup({std::nan(""), 0, 0, 0}), UsageError);
  EXPECT_FALSE(b.has_data(0));
  EXPECT_TRUE(b.has_data(1));
  b.set(5, Eigen::Vector3d(1, 2, 3));
  EXPECT_DOUBLE_EQ(b.value(0, 5), 1);
  EXPECT_DOUBLE_EQ(b.value(1, 5), 2);
  EXPECT_DOUBLE_EQ(b.value(2, 5), 3);
  EXPECT_DOUBLE_EQ(b.stored(2, 5), 3 / (1.66 / 1500));
}

TEST(Merl, TruncatedOrOversizedFilesAreOneClearLine) {
  test::ScratchDir dir;
  const auto good = dir / "good.binary", p = dir / "t.binary";
  write_merl(good, MerlBrdf());
  for (std::uintmax_t size : {std::uintmax_t(0), std::uintmax_t(5), std::uintmax_t(12), std::uintmax_t(1000),
                              std::uintmax_t(34992011), std::uintmax_t(34992020)}) {
    std::filesystem::copy_file(good, p, std::filesystem::copy_options::overwrite_existing);
    truncate_to(p, size);
    const std::string msg = test::input_error_text([&] { read_merl(p); });
    EXPECT_NE(msg.find(p.string()), std::string::npos) << msg;
    EXPECT_NE(msg.find(std::to_string(size) + " bytes"), std::string::npos) << msg;
    EXPECT_NE(msg.find("expected 34992012 bytes"), std::string::npos) << msg;
    EXPECT_EQ(msg.find('\n'), std::string::npos);
  }
}

TEST(Merl, WrongDimensionsAndValuesAreRejected) {
  test::ScratchDir dir;
  const auto p = dir / "d.binary";
  write_merl(p, MerlBrdf());
  {
    std::fstream f(p, std::ios::in | std::ios::out | std::ios::binary);
    const std::int32_t dims[3] = {90, 90, 360};
    f.write(reinterpret_cast<const char*>(dims), 12);
  }
  std::string msg = test::input_error_text([&] { read_merl(p); });
  EXPECT_NE(msg.find("90 x 90 x 360, expected 90 x 90 x 180"), std::string::npos) << msg;

  MerlBrdf b;
  b.raw[N + 180 * 90 * 3 + 2] = std::nan("");
  write_merl(p, b);
  msg = test::input_error_text([&] { read_merl(p); });
  EXPECT_NE(msg.find("green plane"), std::string::npos) << msg;
  EXPECT_NE(msg.find("theta_h 3, theta_d 0, phi_d 2"), std::string::npos) << msg;

  EXPECT_NE(test::input_error_text([&] { read_merl(dir / "missing.binary"); }).find("missing.binary"),
            std::string::npos);
  EXPECT_THROW(read_merl(dir.path()), InputError);
  MerlBrdf bad;
  bad.raw.resize(10);
  EXPECT_THROW(write_merl(p, bad), UsageError);
}

}  // namespace
}  // namespace specula::codec

namespace specula {

TEST(Merl, ScaleGivesTheValuesInOneOverSrAndUnscaleUndoesIt) {
  codec::MerlBrdf b;
  for (std::size_t i = 0; i < b.raw.size(); i += 7) b.raw[i] = double(i % 1000) / 3;
  b.raw[5] = -2;  // no data stays as it is
  codec::MerlBrdf s = b;
  s.scale();
  for (std::size_t c = 0; c < 3; ++c)
    for (std::size_t cell : {std::size_t(0), std::size_t(7), std::size_t(12345), brdf::kMerlCells - 1}) {
      const double stored = b.stored(int(c), cell);
      EXPECT_EQ(s.stored(int(c), cell), stored >= 0 ? b.value(int(c), cell) : stored);
    }
  EXPECT_EQ(s.raw[5], -2);
  s.unscale();
  for (std::size_t i = 0; i < b.raw.size(); i += 997) EXPECT_NEAR(s.raw[i], b.raw[i], 1e-12 * (1 + b.raw[i]));
}

}  // namespace specula
