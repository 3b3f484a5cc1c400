#include "specula/codec/rgl_bsdf.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>

#include "specula/core/error.h"

namespace specula::codec {
namespace {

using Shape = std::vector<std::uint64_t>;

std::string shape_text(const Shape& s) {
  std::string t = "[";
  for (std::size_t i = 0; i < s.size(); ++i) t += (i ? ", " : "") + std::to_string(s[i]);
  return t + "]";
}

const TensorField& need(const TensorFile& f, std::string_view name, std::size_t rank, TensorType type,
                        const std::string& label) {
  const TensorField* x = f.find(name);
  if (!x) throw InputError(label + ": not an RGL material: tensor field '" + std::string(name) + "' is missing");
  if (x->shape.size() != rank)
    throw InputError(label + ": field '" + x->name + "' has rank " + std::to_string(x->shape.size()) + " (shape " +
                     shape_text(x->shape) + "); the format needs rank " + std::to_string(rank));
  if (x->type != type)
    throw InputError(label + ": field '" + x->name + "' is " + tensor_type_name(x->type) + "; the format needs " +
                     tensor_type_name(type));
  return *x;
}

void expect_extent(const TensorField& f, std::size_t dim, std::uint64_t want, const std::string& what,
                   const std::string& label) {
  if (f.shape[dim] != want)
    throw InputError(label + ": field '" + f.name + "' has shape " + shape_text(f.shape) + "; extent " +
                     std::to_string(dim) + " must be " + std::to_string(want) + " (" + what + ")");
}

void check_values(const std::vector<float>& v, const std::string& name, bool non_negative, const std::string& label) {
  for (std::size_t i = 0; i < v.size(); ++i)
    if (!std::isfinite(v[i]) || (non_negative && v[i] < 0))
      throw InputError(label + ": field '" + name + "' holds " + std::to_string(v[i]) + " at element " +
                       std::to_string(i) +
                       (non_negative ? "; its values must be finite and non-negative" : "; its values must be finite"));
}

// Each of `slices` consecutive blocks must have a positive sum (the renderers normalise each into a density).
void check_density(const std::vector<float>& v, std::size_t slices, const std::string& name, const std::string& label) {
  const std::size_t n = v.size() / slices;
  for (std::size_t s = 0; s < slices; ++s) {
    double sum = 0;
    for (std::size_t i = 0; i < n; ++i) sum += v[s * n + i];
    if (!(sum > 1e-30))
      throw InputError(label + ": field '" + name + "' is zero everywhere for incident direction " + std::to_string(s) +
                       "; a renderer cannot normalise it into a density");
  }
}

}  // namespace

TensorFile to_tensor(const RglBsdf& b) {
  const std::size_t t = b.theta_i.size(), c = b.channels(), r = b.resolution;
  TensorFile f;
  f.fields.push_back({"version", TensorType::uint32, {b.version.size()}, {}});
  f.fields.back().data.resize(b.version.size() * 4);
  std::memcpy(f.fields.back().data.data(), b.version.data(), b.version.size() * 4);
  f.fields.push_back(uint8_field("description", {b.description.size()},
                                 {reinterpret_cast<const std::uint8_t*>(b.description.data()), b.description.size()}));
  f.fields.push_back(float32_field("phi_i", {b.phi_i.size()}, b.phi_i));
  f.fields.push_back(float32_field("theta_i", {t}, b.theta_i));
  f.fields.push_back(float32_field("sigma", {b.sigma_height, b.sigma_width}, b.sigma));
  f.fields.push_back(float32_field("ndf", {b.ndf_height, b.ndf_width}, b.ndf));
  f.fields.push_back(float32_field("vndf", {b.phi_i.size(), t, b.vndf_height, b.vndf_width}, b.vndf));
  f.fields.push_back(float32_field("luminance", {b.phi_i.size(), t, r, r}, b.luminance));
  if (b.rgb) {
    f.fields.push_back(float32_field("rgb", {b.phi_i.size(), t, 3, r, r}, b.values));
  } else {
    f.fields.push_back(float32_field("wavelengths", {c}, b.wavelengths));
    f.fields.push_back(float32_field("spectra", {b.phi_i.size(), t, c, r, r}, b.values));
  }
  const std::uint8_t jacobian = b.jacobian ? 1 : 0;
  f.fields.push_back(uint8_field("jacobian", {1}, {&jacobian, 1}));
  f.fields.push_back(uint8_field("valid", {b.valid.size()}, b.valid));
  return f;
}

RglBsdf from_tensor(const TensorFile& f, const std::string& label) {
  RglBsdf b;
  const auto& phi_i = need(f, "phi_i", 1, TensorType::float32, label);
  const auto& theta_i = need(f, "theta_i", 1, TensorType::float32, label);
  const auto& description = need(f, "description", 1, TensorType::uint8, label);
  const auto& jacobian = need(f, "jacobian", 1, TensorType::uint8, label);
  const auto& ndf = need(f, "ndf", 2, TensorType::float32, label);
  const auto& sigma = need(f, "sigma", 2, TensorType::float32, label);
  const auto& vndf = need(f, "vndf", 4, TensorType::float32, label);
  const auto& luminance = need(f, "luminance", 4, TensorType::float32, label);
  b.rgb = f.find("wavelengths") == nullptr;
  if (b.rgb && !f.find("rgb"))
    throw InputError(label + ": not an RGL material: neither 'wavelengths' + 'spectra' nor 'rgb' is present");
  const auto& values = need(f, b.rgb ? "rgb" : "spectra", 5, TensorType::float32, label);
  if (!b.rgb) b.wavelengths = float32_values(need(f, "wavelengths", 1, TensorType::float32, label), label);

  b.phi_i = float32_values(phi_i, label);
  if (b.phi_i.size() != 1)
    throw InputError(label + ": anisotropic material (" + std::to_string(b.phi_i.size()) +
                     " phi_i values); specula reads isotropic RGL files only");
  b.theta_i = float32_values(theta_i, label);
  const std::size_t t = b.theta_i.size();
  if (t < 1) throw InputError(label + ": field 'theta_i' is empty");
  for (std::size_t i = 0; i < t; ++i)
    if (!(b.theta_i[i] >= 0 && b.theta_i[i] <= float(std::numbers::pi / 2) + 1e-6f) ||
        (i && !(b.theta_i[i] > b.theta_i[i - 1])))
      throw InputError(label + ": field 'theta_i' holds " + std::to_string(b.theta_i[i]) + " at element " +
                       std::to_string(i) + "; it must ascend within [0, pi/2]");
  if (jacobian.shape[0] != 1) expect_extent(jacobian, 0, 1, "one flag", label);
  b.jacobian = std::to_integer<int>(jacobian.data[0]) != 0;
  b.description.assign(reinterpret_cast<const char*>(description.data.data()), description.data.size());

  b.ndf_height = ndf.shape[0];
  b.ndf_width = ndf.shape[1];
  b.sigma_height = sigma.shape[0];
  b.sigma_width = sigma.shape[1];
  for (const TensorField* x : {&ndf, &sigma})
    if (x->shape[0] < 2 || x->shape[1] < 2)
      throw InputError(label + ": field '" + x->name + "' has shape " + shape_text(x->shape) +
                       "; it needs at least 2 x 2 nodes");
  expect_extent(vndf, 0, 1, "phi_i", label);
  expect_extent(vndf, 1, t, "theta_i", label);
  if (vndf.shape[2] < 2 || vndf.shape[3] < 2)
    throw InputError(label + ": field 'vndf' has shape " + shape_text(vndf.shape) + "; it needs at least 2 x 2 nodes");
  b.vndf_height = vndf.shape[2];
  b.vndf_width = vndf.shape[3];
  expect_extent(luminance, 0, 1, "phi_i", label);
  expect_extent(luminance, 1, t, "theta_i", label);
  b.resolution = luminance.shape[2];
  if (b.resolution < 2)
    throw InputError(label + ": field 'luminance' has shape " + shape_text(luminance.shape) +
                     "; it needs at least 2 x 2 nodes");
  expect_extent(luminance, 3, b.resolution, "a square sample grid", label);
  expect_extent(values, 0, 1, "phi_i", label);
  expect_extent(values, 1, t, "theta_i", label);
  expect_extent(values, 2, b.rgb ? 3 : b.wavelengths.size(), b.rgb ? "3 RGB channels" : "the wavelengths", label);
  expect_extent(values, 3, b.resolution, "the luminance grid", label);
  expect_extent(values, 4, b.resolution, "the luminance grid", label);
  if (!b.rgb) {
    if (b.wavelengths.empty()) throw InputError(label + ": field 'wavelengths' is empty");
    for (std::size_t i = 0; i < b.wavelengths.size(); ++i)
      if (!(b.wavelengths[i] > 0 && std::isfinite(b.wavelengths[i])) ||
          (i && !(b.wavelengths[i] > b.wavelengths[i - 1])))
        throw InputError(label + ": field 'wavelengths' holds " + std::to_string(b.wavelengths[i]) + " at element " +
                         std::to_string(i) + "; wavelengths must be positive and ascending");
  }
  b.ndf = float32_values(ndf, label);
  b.sigma = float32_values(sigma, label);
  b.vndf = float32_values(vndf, label);
  b.luminance = float32_values(luminance, label);
  b.values = float32_values(values, label);
  check_values(b.ndf, "ndf", true, label);
  check_values(b.sigma, "sigma", true, label);
  for (std::size_t i = 0; i < b.sigma.size(); ++i)
    if (!(b.sigma[i] > 0))
      throw InputError(label + ": field 'sigma' holds 0 at element " + std::to_string(i) +
                       "; the renderers divide by it");
  check_values(b.vndf, "vndf", true, label);
  check_values(b.luminance, "luminance", true, label);
  check_values(b.values, values.name, false, label);
  check_density(b.vndf, t, "vndf", label);
  check_density(b.luminance, t, "luminance", label);
  if (const TensorField* valid = f.find("valid"))
    if (valid->type == TensorType::uint8)
      b.valid.assign(reinterpret_cast<const std::uint8_t*>(valid->data.data()),
                     reinterpret_cast<const std::uint8_t*>(valid->data.data()) + valid->data.size());
  if (const TensorField* version = f.find("version"); version && version->type == TensorType::uint32) {
    b.version.resize(version->data.size() / 4);
    std::memcpy(b.version.data(), version->data.data(), b.version.size() * 4);
  }
  return b;
}

RglBsdf read_rgl_bsdf(const std::filesystem::path& path) {
  return from_tensor(read_tensor_file(path), path.filename().string());
}

void write_rgl_bsdf(const std::filesystem::path& path, const RglBsdf& bsdf) {
  write_tensor_file(path, to_tensor(bsdf));
}

}  // namespace specula::codec
