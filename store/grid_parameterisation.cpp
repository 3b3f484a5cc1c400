// The optional `parameterisation` group of a BRDF grid: the RGL file it was imported from, as an export needs it
// (docs/store-format.md, "BRDF grids").
#include "specula/store/detail/grid_parameterisation.h"

#include <string>
#include <vector>

#include "specula/core/error.h"
#include "specula/store/detail/objects.h"

namespace specula::store {
namespace {

constexpr long long kParameterisationVersion = 1;

void write_floats(hid_t g, const char* name, const std::vector<float>& v, std::vector<hsize_t> dims,
                  const std::string& ctx) {
  h5::Id space(h5::check(H5Screate_simple(int(dims.size()), dims.data(), nullptr), ctx, "H5Screate_simple"));
  h5::Id ds(h5::check(H5Dcreate2(g, name, H5T_IEEE_F32LE, space, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT), ctx,
                      std::string("cannot create ") + name));
  h5::check(H5Dwrite(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), ctx,
            std::string("cannot write ") + name);
}

std::vector<float> read_floats(hid_t g, const char* name, std::size_t rank, std::vector<hsize_t>& dims,
                               const std::string& ctx) {
  h5::Id ds = open_dataset(g, name, ctx);
  dims = h5::shape(ds, ctx);
  if (dims.size() != rank)
    throw InputError(ctx + "/" + name + ": rank " + std::to_string(dims.size()) + "; expected " + std::to_string(rank));
  std::size_t n = 1;
  for (const hsize_t d : dims) n *= std::size_t(d);
  std::vector<float> v(n);
  if (n)
    h5::check(H5Dread(ds, H5T_NATIVE_FLOAT, H5S_ALL, H5S_ALL, H5P_DEFAULT, v.data()), ctx,
              "cannot read " + std::string(name));
  return v;
}

}  // namespace

std::string parameterisation_problem(const GridParameterisation& p) {
  if (p.phi_i.size() != 1) return "phi_i must hold one value (isotropic)";
  if (p.theta_i.empty()) return "theta_i is empty";
  if (p.ndf_width < 2 || p.ndf_height < 2 || p.ndf.size() != p.ndf_width * p.ndf_height)
    return "ndf must be at least 2 x 2 and hold height x width values";
  if (p.sigma_width < 2 || p.sigma_height < 2 || p.sigma.size() != p.sigma_width * p.sigma_height)
    return "sigma must be at least 2 x 2 and hold height x width values";
  if (p.vndf_width < 2 || p.vndf_height < 2 || p.vndf.size() != p.theta_i.size() * p.vndf_width * p.vndf_height)
    return "vndf must be at least 2 x 2 per theta_i and hold theta_i x height x width values";
  if (p.resolution < 2) return "the sample grid needs at least 2 nodes per side";
  return {};
}

void write_parameterisation(hid_t grid, const GridParameterisation& p, const std::string& ctx) {
  if (const std::string e = parameterisation_problem(p); !e.empty()) throw UsageError(ctx + ": parameterisation: " + e);
  const std::string pctx = ctx + "/parameterisation";
  h5::Id g = make_group(grid, "parameterisation", pctx);
  h5::write_attr(g, "parameterisation_version", kParameterisationVersion, pctx);
  h5::write_attr(g, "kind", std::string_view("rgl"), pctx);
  h5::write_attr(g, "resolution", static_cast<long long>(p.resolution), pctx);
  h5::write_attr(g, "description", std::string_view(p.description), pctx);
  const hsize_t t = p.theta_i.size();
  write_floats(g, "phi_i", p.phi_i, {p.phi_i.size()}, pctx);
  write_floats(g, "theta_i", p.theta_i, {t}, pctx);
  write_floats(g, "ndf", p.ndf, {p.ndf_height, p.ndf_width}, pctx);
  write_floats(g, "sigma", p.sigma, {p.sigma_height, p.sigma_width}, pctx);
  write_floats(g, "vndf", p.vndf, {p.phi_i.size(), t, p.vndf_height, p.vndf_width}, pctx);
}

std::optional<GridParameterisation> read_parameterisation(hid_t grid, const std::string& ctx) {
  if (!h5::exists(grid, "parameterisation")) return std::nullopt;
  const std::string pctx = ctx + "/parameterisation";
  h5::Id g = open_group(grid, "parameterisation", pctx);
  const long long version = h5::read_int_attr(g, "parameterisation_version", pctx);
  if (version < 1 || version > kParameterisationVersion)
    throw InputError(pctx + ": parameterisation_version " + std::to_string(version) + "; this specula reads 1");
  if (const std::string kind = h5::read_string_attr(g, "kind", pctx); kind != "rgl")
    throw InputError(pctx + ": kind '" + kind + "'; this specula reads 'rgl'");
  GridParameterisation p;
  const long long resolution = h5::read_int_attr(g, "resolution", pctx);
  p.resolution = resolution > 0 ? std::size_t(resolution) : 0;
  p.description = h5::has_attr(g, "description") ? h5::read_string_attr(g, "description", pctx) : "";
  std::vector<hsize_t> d;
  p.phi_i = read_floats(g, "phi_i", 1, d, pctx);
  p.theta_i = read_floats(g, "theta_i", 1, d, pctx);
  p.ndf = read_floats(g, "ndf", 2, d, pctx);
  p.ndf_height = d[0];
  p.ndf_width = d[1];
  p.sigma = read_floats(g, "sigma", 2, d, pctx);
  p.sigma_height = d[0];
  p.sigma_width = d[1];
  p.vndf = read_floats(g, "vndf", 4, d, pctx);
  if (d[0] != p.phi_i.size() || d[1] != p.theta_i.size())
    throw InputError(pctx + "/vndf: its first extents must be phi_i's and theta_i's");
  p.vndf_height = d[2];
  p.vndf_width = d[3];
  if (const std::string e = parameterisation_problem(p); !e.empty()) throw InputError(pctx + ": " + e);
  return p;
}

}  // namespace specula::store
