// .spc formats 2 and 3, the transform method: the magnitude and shape channels filled where the grid has no data,
// folded about phi_d = pi/2, transformed by a 3-D CDF 9/7 wavelet, quantised with steps chosen for the rendered
// appearance and coded by the context-modelled cube coder. Format 3 adds a step profile over theta_d (the grazing
// factor); a file with none (factor 1) is written as format 2, byte for byte as before it.
#include <algorithm>
#include <array>
#include <cmath>

#include "specula/codec/cube_coder.h"
#include "specula/codec/spc_detail.h"
#include "specula/codec/wavelet.h"
#include "specula/core/parallel.h"

namespace specula::codec::detail {
namespace {

using wavelet::CubeLayout;
constexpr std::size_t kFold = std::size_t(kMerlPhiD) / 2;  // phi_d folded about pi/2: 90 sums, 90 differences
constexpr std::size_t kCube = std::size_t(kMerlThetaH) * kMerlThetaD * kFold;
constexpr double kRounding = 0.3;        // |w| / step + kRounding rounded down: a dead zone around 0
constexpr double kReconstruction = 0.1;  // a non-zero code q decodes to sign(q) (|q| + 0.1) step
constexpr std::int32_t kMaxCode = 1 << 28;
enum class Validity : std::uint8_t { all = 0, horizon = 1, coded = 2 };

// 1 for the cells whose centre has both directions above the horizon.
const std::vector<std::uint8_t>& horizon_mask() {
  static const std::vector<std::uint8_t> m = [] {
    std::vector<std::uint8_t> v(kMerlCells);
    for (std::size_t c = 0; c < kMerlCells; ++c) v[c] = brdf::merl_cell_valid(brdf::merl_cell(c));
    return v;
  }();
  return m;
}
constexpr std::array<std::size_t, 3> kGridDims{std::size_t(kMerlThetaH), std::size_t(kMerlThetaD),
                                               std::size_t(kMerlPhiD)};

CubeLayout cube_layout(int levels) { return {{std::size_t(kMerlThetaH), std::size_t(kMerlThetaD), kFold}, levels}; }

// The fields of a format-2 file that decoding needs besides the streams.
struct Transform {
  int levels = 4;
  double step_y = 0, step_c = 0, frequency = 1, reconstruction = kReconstruction;
  double specular = 1, extent = 1;  // steps times specular at theta_h index 0, rising linearly to 1 at `extent`
  double grazing = 1;               // steps times 1 at theta_d index 0, changing linearly to `grazing` at index 90
  std::uint32_t version() const { return grazing == 1 ? 2 : 3; }
  double step(std::size_t channel) const { return channel == 0 ? step_y : step_c; }
};

// Calls f(index, step) for every coefficient of a cube of channel `channel`, the step of its subband: the
// channel's step, times frequency^(levels - 1 - l) for the detail bands of level l (0 finest), divided by the
// subband's synthesis norm so that a step is what an error costs in the channel's own values; and times the
// specular factor near the specular peak: specular + (1 - specular) min(1, h / extent), h the theta_h index its
// support is centred on ((offset in the subband + 1/2) 2^(l + 1), or 2^levels for the final low cube); and times
// the grazing profile 1 + (grazing - 1) min(1, d / 90), d the theta_d index its support is centred on (alike).
template <class F>
void for_each_coefficient(const CubeLayout& c, const Transform& t, std::size_t channel, F&& f) {
  const std::size_t s1 = c.dims[2], s0 = c.dims[1] * c.dims[2];
  auto band = [&](int l, int o, double step, double spread) {
    const auto r0 = c.range(l, o, 0), r1 = c.range(l, o, 1), r2 = c.range(l, o, 2);
    for (std::size_t i = r0[0]; i < r0[1]; ++i) {
      const double h = (double(i - r0[0]) + 0.5) * spread;
      const double at = step * (t.specular + (1 - t.specular) * std::min(1.0, h / t.extent));
      for (std::size_t j = r1[0]; j < r1[1]; ++j) {
        const double d = (double(j - r1[0]) + 0.5) * spread;
        const double at_d = t.grazing == 1 ? at : at * (1 + (t.grazing - 1) * std::min(1.0, d / 90.0));
        for (std::size_t k = r2[0]; k < r2[1]; ++k) f(i * s0 + j * s1 + k, at_d);
      }
    }
  };
  const double base = t.step(channel);
  band(c.levels, 0, base / c.synthesis_norm(c.levels, 0), std::ldexp(1.0, c.levels));
  for (int l = c.levels - 1; l >= 0; --l)
    for (int o = 1; o < 8; ++o)
      band(l, o, base * std::pow(t.frequency, c.levels - 1 - l) / c.synthesis_norm(l, o), std::ldexp(1.0, l + 1));
}

// Fills the cells of a 90 x 90 x 180 channel where `known` is 0 so that the channel stays smooth for the transform:
// along theta_d, then phi_d, then theta_h, each gap between known cells linearly and each end with its nearest
// known value; cells on lines with nothing known wait for the next axis (and are 0 if no cell is known).
void fill(std::span<float> v, std::vector<std::uint8_t> known) {
  const std::array<std::size_t, 3> n{std::size_t(kMerlThetaH), std::size_t(kMerlThetaD), std::size_t(kMerlPhiD)};
  const std::array<std::size_t, 3> stride{kSlab, std::size_t(kMerlPhiD), 1};
  for (const std::size_t axis : {std::size_t(1), std::size_t(2), std::size_t(0)}) {
    const std::size_t a = (axis + 1) % 3, b = (axis + 2) % 3;
    for (std::size_t i = 0; i < n[a]; ++i)
      for (std::size_t j = 0; j < n[b]; ++j) {
        const std::size_t base = i * stride[a] + j * stride[b];
        std::ptrdiff_t last = -1;
        for (std::size_t t = 0; t <= n[axis]; ++t) {
          if (t < n[axis] && !known[base + t * stride[axis]]) continue;
          if (t == n[axis] && last < 0) break;  // nothing known on this line
          const float right = t < n[axis] ? v[base + t * stride[axis]] : v[base + std::size_t(last) * stride[axis]];
          const float left = last >= 0 ? v[base + std::size_t(last) * stride[axis]] : right;
          for (std::size_t u = std::size_t(last + 1); u < t; ++u) {
            const double w =
                last >= 0 && t < n[axis] ? double(u - std::size_t(last)) / double(t - std::size_t(last)) : 0.0;
            v[base + u * stride[axis]] = float(left + w * (right - left));
            known[base + u * stride[axis]] = 1;
          }
          last = std::ptrdiff_t(t);
        }
      }
  }
  for (std::size_t c = 0; c < v.size(); ++c)
    if (!known[c]) v[c] = 0;
}

// A filled channel folded about phi_d = pi/2 into its sum and difference cubes (isotropic reciprocal BRDFs are
// even there, so the difference is near zero): S = (v(p) + v(179 - p)) / 2, D = (v(p) - v(179 - p)) / 2.
void fold(std::span<const float> v, Buffer<float>& sum, Buffer<float>& diff) {
  sum.resize(kCube);
  diff.resize(kCube);
  for (std::size_t hd = 0; hd < std::size_t(kMerlThetaH) * kMerlThetaD; ++hd)
    for (std::size_t p = 0; p < kFold; ++p) {
      const float a = v[hd * kMerlPhiD + p], b = v[hd * kMerlPhiD + kMerlPhiD - 1 - p];
      sum[hd * kFold + p] = 0.5f * (a + b);
      diff[hd * kFold + p] = 0.5f * (a - b);
    }
}

// The magnitude and shape channels of a grid on a basis, transformed: 2 (k + 1) cubes (sum, difference per channel).
struct Model {
  std::size_t bands = 0, k = 0;
  double scale = 1, s = 1;
  std::vector<std::uint8_t> valid;
  std::uint64_t n_valid = 0;
  Validity validity = Validity::coded;
  std::vector<Buffer<float>> cubes;
};

Model transform_model(const store::Grid& grid, const SpcBasis& basis, const SpcTransformOptions& o) {
  Model md;
  md.bands = grid.bands();
  md.k = basis.k();
  md.scale = grid.scale;
  const std::size_t bands = md.bands, k = md.k;
  std::vector<float> mag;
  md.n_valid = magnitudes(grid, mag, md.valid);
  md.s = magnitude_scale(mag, md.valid, o.magnitude_scale);
  // Large scratch (Buffer, core/buffer.h): an encode's target search builds a model per k it tries.
  std::vector<Buffer<float>> ch(k + 1);
  for (auto& c : ch) c.assign(kMerlCells, 0.0f);
  std::vector<std::uint8_t> shaped(kMerlCells, 0);
  const bool all = md.n_valid == kMerlCells, horizon = md.valid == horizon_mask();
  md.validity = all ? Validity::all : horizon ? Validity::horizon : Validity::coded;
  parallel_for(
      kMerlCells,
      [&](std::size_t c) {
        if (!md.valid[c]) return;
        const double m = mag[c];
        ch[0][c] = float(std::log1p(m / md.s));
        if (!(m > 0)) return;
        shaped[c] = 1;
        for (std::size_t j = 0; j < k; ++j) {
          double v = 0;
          for (std::size_t b = 0; b < bands; ++b)
            v += basis.rows(Eigen::Index(j), Eigen::Index(b)) * grid.brdf[b * kMerlCells + c];
          ch[j + 1][c] = float(v / m);
        }
      },
      kSlab);
  md.cubes.resize(2 * (k + 1));
  const CubeLayout layout = cube_layout(o.levels);
  parallel_for(
      k + 1,
      [&](std::size_t j) {
        fill(ch[j], j == 0 ? md.valid : shaped);
        fold(ch[j], md.cubes[2 * j], md.cubes[2 * j + 1]);
        Buffer<float>().swap(ch[j]);
        wavelet::forward_cube(md.cubes[2 * j], layout);
        wavelet::forward_cube(md.cubes[2 * j + 1], layout);
      },
      1);
  return md;
}

std::vector<Buffer<std::int32_t>> quantise(const Model& md, const Transform& t) {
  std::vector<Buffer<std::int32_t>> q(md.cubes.size());
  const CubeLayout layout = cube_layout(t.levels);
  parallel_for(
      md.cubes.size(),
      [&](std::size_t cube) {
        const Buffer<float>& w = md.cubes[cube];
        q[cube].assign(kCube, 0);
        std::int32_t* out = q[cube].data();
        for_each_coefficient(layout, t, cube / 2, [&](std::size_t i, double step) {
          const double a = std::floor(std::abs(double(w[i])) / step + kRounding);
          if (!(a < kMaxCode))
            throw UsageError("encode: a transform coefficient needs a code beyond 2^28; raise the step");
          out[i] = std::int32_t(w[i] < 0 ? -a : a);
        });
      },
      1);
  return q;
}

// The coefficient form of quantised cubes: dequantised, inverse-transformed, unfolded, and per valid cell
// a_j = s expm1(max(0, y')) c'_j.
SpcCoefficients reconstruct(const std::vector<Buffer<std::int32_t>>& q, const Transform& t, std::size_t k, double s,
                            const std::vector<std::uint8_t>& valid, const std::string& label) {
  const CubeLayout layout = cube_layout(t.levels);
  // The channels and the coefficient form are sized unwritten and first written by the threads that fill them: every
  // cell of a channel is written below, and the form's cells without data are zeroed in its fill.
  std::vector<Buffer<float>> channel(k + 1);
  parallel_for(
      k + 1,
      [&](std::size_t j) {
        channel[j].resize(kMerlCells);
        std::array<Buffer<float>, 2> w;
        for (std::size_t half = 0; half < 2; ++half) {
          w[half].assign(kCube, 0.0f);
          const std::int32_t* in = q[2 * j + half].data();
          float* out = w[half].data();
          for_each_coefficient(layout, t, j, [&](std::size_t i, double step) {
            const std::int32_t v = in[i];
            out[i] = v == 0 ? 0.0f : float((v < 0 ? -1.0 : 1.0) * (std::abs(double(v)) + t.reconstruction) * step);
          });
          wavelet::inverse_cube(w[half], layout);
        }
        float* v = channel[j].data();
        for (std::size_t hd = 0; hd < std::size_t(kMerlThetaH) * kMerlThetaD; ++hd)
          for (std::size_t p = 0; p < kFold; ++p) {
            const float sum = w[0][hd * kFold + p], diff = w[1][hd * kFold + p];
            v[hd * kMerlPhiD + p] = sum + diff;
            v[hd * kMerlPhiD + kMerlPhiD - 1 - p] = sum - diff;
          }
      },
      1);
  SpcCoefficients out;
  out.values.resize(k * kMerlCells);
  parallel_for(
      kMerlCells,
      [&](std::size_t c) {
        if (!valid[c]) {
          std::fill_n(out.values.begin() + std::ptrdiff_t(c * k), k, 0.0f);
          return;
        }
        const double m = s * std::expm1(std::max(0.0, double(channel[0][c])));
        for (std::size_t j = 0; j < k; ++j) {
          const float a = float(m * double(channel[j + 1][c]));
          if (!std::isfinite(a))
            throw InputError(
                label + ": .spc coefficients decode beyond float range; the file was not written by specula encode");
          out.values[c * k + j] = a;
        }
      },
      kSlab);
  out.valid = valid;
  return out;
}

std::vector<std::uint8_t> pack_v2(const Model& md, const SpcBasis& basis, const store::Grid& grid, const Transform& t,
                                  const std::vector<Buffer<std::int32_t>>& q, const std::string& source) {
  std::vector<std::vector<std::uint8_t>> streams(q.size());
  const CubeLayout layout = cube_layout(t.levels);
  parallel_for(
      q.size(), [&](std::size_t i) { streams[i] = encode_cube(q[i], layout); }, 1);
  std::size_t total = 1024 + 8 * md.bands * (md.k + 1) + grid.units.size() + source.size() + basis.reference.size();
  for (const auto& st : streams) total += 4 + st.size();
  std::vector<std::uint8_t> out;
  out.reserve(total);
  put_head(out, t.version(), md.bands, md.k, md.scale, md.s);
  const auto& wl = grid.wavelengths;
  const bool uniform = wl.uniform() && wl.size() > 1;
  put(out, std::uint8_t(uniform ? 0 : 1));
  if (uniform) {
    put(out, wl.front());
    put(out, wl.step());
  } else {
    for (const double w : wl.values()) put(out, w);
  }
  put_basis_and_labels(out, basis, md.k, md.bands, grid.units, source);
  put(out, std::uint64_t(md.n_valid));
  put(out, std::uint8_t(md.validity));
  if (md.validity == Validity::coded) {
    const auto z = encode_mask(md.valid, horizon_mask(), kGridDims);
    put(out, std::uint32_t(z.size()));
    put_bytes(out, z.data(), z.size());
  }
  put(out, std::uint8_t(t.levels));
  put(out, t.step_y);
  put(out, t.step_c);
  put(out, t.frequency);
  put(out, t.reconstruction);
  put(out, t.specular);
  put(out, t.extent);
  if (t.version() == 3) put(out, t.grazing);
  for (const auto& s : streams) {
    put(out, std::uint32_t(s.size()));
    put_bytes(out, s.data(), s.size());
  }
  put(out, crc32_of(out));
  return out;
}

Transform transform_of(const SpcTransformOptions& o, double step) {
  return {o.levels,
          step,
          step * o.shape_step_ratio,
          o.frequency_factor,
          kReconstruction,
          o.specular_factor,
          o.specular_extent,
          o.grazing_factor};
}

// The finest step (of options o's ratios) whose codes all stay below kMaxCode / 2.
double finest_step(const Model& md, const SpcTransformOptions& o) {
  const Transform unit = transform_of(o, 1);
  const CubeLayout layout = cube_layout(unit.levels);
  std::vector<double> need(md.cubes.size(), 0);
  parallel_for(
      md.cubes.size(),
      [&](std::size_t cube) {
        for_each_coefficient(layout, unit, cube / 2, [&](std::size_t i, double step) {
          need[cube] = std::max(need[cube], std::abs(double(md.cubes[cube][i])) / step);
        });
      },
      1);
  return *std::max_element(need.begin(), need.end()) / (kMaxCode / 2);
}

void check_transform_options(const store::Grid& grid, const SpcBasis& basis, const SpcTransformOptions& o) {
  if (grid.brdf.size() != grid.bands() * kMerlCells)
    throw UsageError("encode: grid values do not match bands x 90 x 90 x 180");
  if (!(std::isfinite(o.step) && o.step > 0 && o.step <= 10))
    throw UsageError("step = " + std::to_string(o.step) + ": give a number in (0, 10]");
  if (!(std::isfinite(o.shape_step_ratio) && o.shape_step_ratio > 0 && o.shape_step_ratio <= 1000))
    throw UsageError("shape_step_ratio = " + std::to_string(o.shape_step_ratio) + ": give a number in (0, 1000]");
  if (!(std::isfinite(o.frequency_factor) && o.frequency_factor >= 1 && o.frequency_factor <= 16))
    throw UsageError("frequency_factor = " + std::to_string(o.frequency_factor) + ": give a number in [1, 16]");
  if (o.levels < 1 || o.levels > 5) throw UsageError("levels = " + std::to_string(o.levels) + ": give 1 to 5");
  if (!(std::isfinite(o.specular_factor) && o.specular_factor > 0 && o.specular_factor <= 1))
    throw UsageError("specular_factor = " + std::to_string(o.specular_factor) + ": give a number in (0, 1]");
  if (!(std::isfinite(o.specular_extent) && o.specular_extent >= 1 && o.specular_extent <= 90))
    throw UsageError("specular_extent = " + std::to_string(o.specular_extent) + ": give 1 to 90 theta_h indices");
  if (!(std::isfinite(o.grazing_factor) && o.grazing_factor >= 0.0625 && o.grazing_factor <= 16))
    throw UsageError("grazing_factor = " + std::to_string(o.grazing_factor) + ": give a number in [1/16, 16]");
  if (!(std::isfinite(o.magnitude_scale) && o.magnitude_scale >= 0))
    throw UsageError("magnitude scale must be finite and >= 0 (0: automatic)");
  if (!(std::isfinite(grid.scale) && grid.scale > 0)) throw UsageError("encode: the grid's scale must be positive");
  if (basis.rows.cols() != Eigen::Index(grid.bands()) || !basis.wavelengths.approx_equal(grid.wavelengths))
    throw InputError("the grid has " + grid.wavelengths.describe() + ", basis " + basis.reference + " has " +
                     basis.wavelengths.describe() + "; code a grid with a basis on its own wavelengths");
}

// Errors of a decoding against the grid, for SpcReport (values x scale, 1/sr), and the shape quantisation error.
void measure(const store::Grid& grid, const SpcCoefficients& c, const SpcBasis& basis, std::uint64_t bytes,
             SpcReport& r) {
  const std::size_t bands = grid.bands(), k = c.k();
  std::vector<double> sq(kMerlThetaH, 0), mx(kMerlThetaH, 0), resid(kMerlThetaH, 0), quant(kMerlThetaH, 0);
  parallel_for(
      std::size_t(kMerlThetaH), [&] { return std::vector<float>(bands); },
      [&](std::size_t h, std::vector<float>& x) {
        Eigen::VectorXd r(static_cast<Eigen::Index>(bands)), a(static_cast<Eigen::Index>(k));
        for (std::size_t cell = h * kSlab; cell < (h + 1) * kSlab; ++cell) {
          if (!c.valid[cell]) continue;
          expand_cell(c.basis, c.values.data() + cell * k, x.data(), 1);
          double m = 0;
          for (std::size_t b = 0; b < bands; ++b) {
            const double e = (double(x[b]) - grid.brdf[b * kMerlCells + cell]) * grid.scale;
            sq[h] += e * e;
            mx[h] = std::max(mx[h], std::abs(e));
            r[Eigen::Index(b)] = grid.brdf[b * kMerlCells + cell];
            m += r[Eigen::Index(b)];
          }
          m /= double(bands);
          if (!(m > 0)) continue;
          r /= m;
          const Eigen::VectorXd coef = basis.rows * r;
          const Eigen::VectorXd rk = basis.rows.transpose() * coef;
          for (std::size_t j = 0; j < k; ++j) a[Eigen::Index(j)] = c.values[cell * k + j];
          const double ma = (c.basis.transpose() * a).mean();
          const Eigen::VectorXd rq = ma > 0 ? Eigen::VectorXd(c.basis.transpose() * a / ma) : Eigen::VectorXd(rk);
          resid[h] = std::max(resid[h], (r - rk).cwiseAbs().maxCoeff());
          quant[h] = std::max(quant[h], (rq - rk).cwiseAbs().maxCoeff());
        }
      });
  r = {};
  double total = 0;
  for (int h = 0; h < kMerlThetaH; ++h) {
    total += sq[std::size_t(h)];
    r.max_abs_error = std::max(r.max_abs_error, mx[std::size_t(h)]);
    r.max_shape_residual = std::max(r.max_shape_residual, resid[std::size_t(h)]);
    r.max_quantisation_error = std::max(r.max_quantisation_error, quant[std::size_t(h)]);
  }
  r.input_bytes = std::uint64_t(bands) * kMerlCells * 8;
  r.output_bytes = bytes;
  r.valid_cells = std::uint64_t(std::count(c.valid.begin(), c.valid.end(), std::uint8_t(1)));
  r.rms_error = r.valid_cells ? std::sqrt(total / double(r.valid_cells * bands)) : 0.0;
}

SpcCoefficients with_header(SpcCoefficients c, const store::Grid& grid, const SpcBasis& basis,
                            const std::string& source) {
  c.wavelengths = grid.wavelengths;
  c.basis = basis.rows.cast<float>().cast<double>();  // as the file stores it
  c.scale = grid.scale;
  c.units = grid.units;
  c.source = source;
  c.reference = basis.reference;
  return c;
}

// The file of a transformed model at one step, and what it measures against the grid when asked.
std::vector<std::uint8_t> code_model(const Model& md, const store::Grid& grid, const SpcBasis& basis,
                                     const SpcTransformOptions& o, double step, SpcReport* report,
                                     const std::string& source) {
  const Transform t = transform_of(o, step);
  const auto q = quantise(md, t);
  auto bytes = pack_v2(md, basis, grid, t, q, source);
  if (report) {
    const SpcCoefficients c = with_header(reconstruct(q, t, md.k, md.s, md.valid, "encode"), grid, basis, source);
    measure(grid, c, basis, bytes.size(), *report);
    report->magnitude_scale = md.s * md.scale;
    report->magnitude_step = t.step_y;
    report->shape_step = t.step_c;
  }
  return bytes;
}

SpcCoefficients decode_v2(std::span<const std::uint8_t> bytes, const std::string& label, bool header_only) {
  Reader r(bytes.first(bytes.size() - 4), label);
  r.take(sizeof kSpcMagic, "magic");
  const auto version = r.get<std::uint32_t>("version");
  const auto [bands, k] = read_shape(r, label);
  SpcCoefficients c;
  const auto [scale, s] = read_scales(r, label);
  c.scale = scale;
  const auto wl_kind = r.get<std::uint8_t>("wavelength kind");
  std::vector<double> wl(bands);
  if (wl_kind == 0) {
    const double first = r.get<double>("first wavelength"), step = r.get<double>("wavelength step");
    for (std::size_t b = 0; b < bands; ++b) wl[b] = first + double(b) * step;
  } else if (wl_kind == 1) {
    std::memcpy(wl.data(), r.take(8 * bands, "wavelengths"), 8 * bands);
  } else {
    throw InputError(label + ": .spc wavelength kind " + std::to_string(wl_kind) +
                     " is neither 0 (uniform) nor 1 (list)");
  }
  c.wavelengths = checked_wavelengths(std::move(wl), label);
  c.basis = read_basis<float>(r, k, bands, label);
  c.units = r.string("units");
  c.source = r.string("source");
  c.reference = r.string("basis reference");
  if (header_only) return c;
  const auto n_valid = r.get<std::uint64_t>("valid cells");
  const auto kind = r.get<std::uint8_t>("validity kind");
  c.valid.assign(kMerlCells, 0);
  if (kind == std::uint8_t(Validity::all)) {
    std::fill(c.valid.begin(), c.valid.end(), 1);
  } else if (kind == std::uint8_t(Validity::horizon)) {
    c.valid = horizon_mask();
  } else if (kind == std::uint8_t(Validity::coded)) {
    const auto z = r.get<std::uint32_t>("validity");
    if (!decode_mask({r.take(z, "validity"), z}, horizon_mask(), kGridDims, c.valid))
      throw InputError(label + ": .spc validity stream ends before its cells; the file is corrupt");
  } else {
    throw InputError(label + ": .spc validity kind " + std::to_string(kind) +
                     " is not 0 (all), 1 (horizon) or 2 (coded)");
  }
  const auto counted = std::uint64_t(std::count(c.valid.begin(), c.valid.end(), std::uint8_t(1)));
  if (counted != n_valid)
    throw InputError(label + ": .spc validity has " + std::to_string(counted) + " valid cells, the header says " +
                     std::to_string(n_valid));
  Transform t;
  t.levels = r.get<std::uint8_t>("levels");
  t.step_y = r.get<double>("magnitude step");
  t.step_c = r.get<double>("shape step");
  t.frequency = r.get<double>("frequency factor");
  t.reconstruction = r.get<double>("reconstruction offset");
  t.specular = r.get<double>("specular factor");
  t.extent = r.get<double>("specular extent");
  if (version >= 3) {
    t.grazing = r.get<double>("grazing factor");
    if (!(std::isfinite(t.grazing) && t.grazing >= 0.0625 && t.grazing <= 16 && t.grazing != 1))
      throw InputError(label + ": .spc grazing factor " + std::to_string(t.grazing) +
                       " is outside [1/16, 16] or 1 (which format 2 writes)");
  }
  if (t.levels < 1 || t.levels > 5)
    throw InputError(label + ": .spc has " + std::to_string(t.levels) + " levels; 1 to 5 are valid");
  for (const auto& [v, what] : {std::pair{t.step_y, "magnitude step"}, std::pair{t.step_c, "shape step"},
                                std::pair{t.frequency, "frequency factor"}})
    if (!(std::isfinite(v) && v > 0 && v <= 1e6))
      throw InputError(label + ": .spc field '" + what + "' is " + std::to_string(v) + "; it must be in (0, 1e6]");
  if (!(std::isfinite(t.specular) && t.specular > 0 && t.specular <= 1))
    throw InputError(label + ": .spc specular factor " + std::to_string(t.specular) + " is outside (0, 1]");
  if (!(std::isfinite(t.extent) && t.extent >= 1 && t.extent <= 90))
    throw InputError(label + ": .spc specular extent " + std::to_string(t.extent) + " is outside [1, 90]");
  if (!(std::isfinite(t.reconstruction) && std::abs(t.reconstruction) < 1))
    throw InputError(label + ": .spc reconstruction offset " + std::to_string(t.reconstruction) +
                     " is outside (-1, 1)");
  const std::size_t cubes = 2 * (std::size_t(k) + 1);
  std::vector<std::span<const std::uint8_t>> streams(cubes);
  for (std::size_t i = 0; i < cubes; ++i) {
    const auto n = r.get<std::uint32_t>("stream length");
    streams[i] = {r.take(n, "stream"), n};
  }
  if (r.at() != bytes.size() - 4)
    throw InputError(label + ": .spc file has " + std::to_string(bytes.size() - 4 - r.at()) +
                     " unexpected bytes before its CRC");
  std::vector<Buffer<std::int32_t>> q(cubes);
  std::vector<std::uint8_t> ok(cubes, 1);
  const CubeLayout layout = cube_layout(t.levels);
  parallel_for(
      cubes,
      [&](std::size_t i) {
        q[i].assign(kCube, 0);
        ok[i] = decode_cube(streams[i], layout, q[i]);
      },
      1);
  for (std::size_t i = 0; i < cubes; ++i)
    if (!ok[i])
      throw InputError(label + ": .spc stream " + std::to_string(i) + " ends before its cube; the file is corrupt");
  SpcCoefficients v = reconstruct(q, t, k, s, c.valid, label);
  c.values = std::move(v.values);
  return c;
}

}  // namespace

std::vector<std::uint8_t> encode_transform(const store::Grid& grid, const SpcBasis& basis, const SpcTransformOptions& o,
                                           SpcReport* report, const std::string& source) {
  check_transform_options(grid, basis, o);
  return code_model(transform_model(grid, basis, o), grid, basis, o, o.step, report, source);
}

SpcCoefficients decode_transform(std::span<const std::uint8_t> bytes, const std::string& label, bool header_only) {
  return decode_v2(bytes, label, header_only);
}

struct TransformModel::Impl {
  const store::Grid& grid;
  const SpcBasis& basis;
  SpcTransformOptions options;
  Model model;
};

TransformModel::TransformModel(const store::Grid& grid, const SpcBasis& basis, const SpcTransformOptions& o) {
  check_transform_options(grid, basis, o);
  impl_ = std::make_unique<Impl>(Impl{grid, basis, o, transform_model(grid, basis, o)});
}

TransformModel::~TransformModel() = default;

double TransformModel::finest_step() const { return detail::finest_step(impl_->model, impl_->options); }

void TransformModel::decoded(double step, store::Grid& out) const {
  const Impl& m = *impl_;
  const Transform t = transform_of(m.options, step);
  const auto q = quantise(m.model, t);
  expand_spc(with_header(reconstruct(q, t, m.model.k, m.model.s, m.model.valid, "encode"), m.grid, m.basis, ""), out);
}

std::vector<std::uint8_t> TransformModel::code(double step, SpcReport* report, const std::string& source) const {
  return code_model(impl_->model, impl_->grid, impl_->basis, impl_->options, step, report, source);
}

}  // namespace specula::codec::detail
