// A learned BRDF prior (acquire/prior.h) in and out of the store's "priors" kind (store/prior.h).
#include "specula/acquire/prior.h"
#include "specula/store/prior.h"

namespace specula::acquire {

namespace {

store::PriorTables tables_of(const BrdfPrior& p) {
  return {.wavelengths = std::vector<double>(p.wavelengths.values().begin(), p.wavelengths.values().end()),
          .knots = p.knots,
          .variances = p.variances,
          .epsilon = p.epsilon,
          .reference = p.reference,
          .mean = p.mean,
          .ceiling = p.ceiling,
          .components = p.components,
          .training = p.training,
          .retro_exponents = p.retro_exponents,
          .retro_rise = p.retro_rise};
}

BrdfPrior prior_of(store::PriorTables t) {
  BrdfPrior p;
  p.wavelengths = WavelengthGrid(t.wavelengths);
  p.knots = std::move(t.knots);
  p.variances = std::move(t.variances);
  p.epsilon = t.epsilon;
  p.reference = std::move(t.reference);
  p.mean = std::move(t.mean);
  p.ceiling = std::move(t.ceiling);
  p.components = std::move(t.components);
  p.training = std::move(t.training);
  p.retro_exponents = std::move(t.retro_exponents);
  p.retro_rise = std::move(t.retro_rise);
  return p;
}

}  // namespace

void write_prior(store::StoreWriter& out, const std::string& name, const BrdfPrior& p) {
  store::validate_name(name, "prior");
  out.add_prior(name, tables_of(p));
}

BrdfPrior build_prior(std::span<const TrainingGrid> grids, const PriorOptions& options, store::StoreWriter& out,
                      const std::string& name, const std::string& command_line) {
  store::validate_name(name, "prior");
  return build_prior(grids, options, [&](const BrdfPrior& p, const ComponentSource& blocks) {
    store::PriorTables t = tables_of(p);
    t.component_blocks = blocks;
    t.command_line = command_line;
    out.add_prior(name, t);
  });
}

std::vector<std::string> prior_names(const store::Store& in) { return in.objects("priors"); }

BrdfPrior read_prior(const store::Store& in, const std::string& name) {
  return prior_of(in.read_prior(name, valid_cells().size()));
}

BrdfPrior read_prior_tables(const store::Store& in, const std::string& name) {
  return prior_of(in.read_prior(name, valid_cells().size(), false));
}

ComponentSource store_components(const store::Store& in, const std::string& name) {
  return [in, name](std::size_t first, std::size_t count, std::span<float> out) {
    in.read_prior_components(name, first, count, out);
  };
}

}  // namespace specula::acquire
