// The training grids of a prior as `specula prior build` names them (acquire/prior.h): grids of stores, whole stores,
// grids in memory, and whatever else the caller loads.
#include <algorithm>
#include <filesystem>
#include <map>

#include "specula/acquire/prior.h"
#include "specula/core/error.h"
#include "specula/store/object_spec.h"

namespace specula::acquire {
namespace {

// One training grid still to make: a spec, grid `name` of an open store, or a grid made already.
struct StoreGrid {
  store::Store store;
  std::string name;
};
using Entry = std::variant<std::string, StoreGrid, TrainingGrid>;

std::string label_of(const Entry& e) {
  if (const auto* spec = std::get_if<std::string>(&e)) return *spec;
  if (const auto* g = std::get_if<StoreGrid>(&e)) return g->store.path().string() + ":" + g->name;
  return std::get<TrainingGrid>(e).name;
}

// Each source as entries: a whole store (.h5 without :NAME, or an open one) stands for all its grids.
std::vector<Entry> expand(std::span<const TrainingSource> sources) {
  std::vector<Entry> entries;
  for (const auto& source : sources) {
    if (const auto* spec = std::get_if<std::string>(&source)) {
      const std::filesystem::path p(*spec);
      if (p.extension() == ".h5" && !store::parse_object_spec(*spec)) {
        for (const auto& name : store::Store::open(p).grids()) entries.emplace_back(*spec + ":" + name);
      } else {
        entries.emplace_back(*spec);
      }
    } else if (const auto* s = std::get_if<store::Store>(&source)) {
      for (const auto& name : s->grids()) entries.emplace_back(StoreGrid{*s, name});
    } else {
      entries.emplace_back(std::get<TrainingGrid>(source));
    }
  }
  return entries;
}

bool excluded(const std::string& label, std::span<const std::string> exclude) {
  const auto spec = store::parse_object_spec(label);
  const std::string name = spec ? spec->name : label;
  return std::find(exclude.begin(), exclude.end(), name) != exclude.end() ||
         std::find(exclude.begin(), exclude.end(), label) != exclude.end();
}

// A spec's grid: a store's grid streams by rows (each store opened once); anything else is other(spec).
TrainingGrid from_spec(const std::string& spec, std::map<std::string, store::Store>& stores,
                       const std::function<TrainingGrid(const std::string&)>& other) {
  const auto object = store::parse_object_spec(spec);
  if (!object || object->file.extension() != ".h5" || std::filesystem::exists(spec)) return other(spec);
  auto at = stores.find(object->file.string());
  if (at == stores.end()) at = stores.emplace(object->file.string(), store::Store::open(object->file)).first;
  return store_training_grid(at->second, object->name, spec);
}

}  // namespace

std::vector<TrainingGrid> training_grids(std::span<const TrainingSource> sources, std::span<const std::string> exclude,
                                         const std::function<TrainingGrid(const std::string&)>& other,
                                         std::string_view command, std::string_view exclude_name) {
  std::vector<Entry> entries = expand(sources);
  std::erase_if(entries, [&](const Entry& e) { return excluded(label_of(e), exclude); });
  if (entries.size() < 2)
    throw UsageError(std::string(command) + ": give at least 2 training grids (after " + std::string(exclude_name) +
                     ")");
  std::map<std::string, store::Store> stores;
  std::vector<TrainingGrid> grids;
  for (auto& e : entries) {
    if (const auto* spec = std::get_if<std::string>(&e)) {
      grids.push_back(from_spec(*spec, stores, other));
    } else if (const auto* g = std::get_if<StoreGrid>(&e)) {
      grids.push_back(store_training_grid(g->store, g->name, label_of(e)));
    } else {
      grids.push_back(std::move(std::get<TrainingGrid>(e)));
    }
  }
  return grids;
}

TrainingGrid reloaded_training_grid(const std::string& name, const std::function<store::Grid()>& load) {
  const store::Grid first = load();
  return {.name = name,
          .wavelengths = first.wavelengths,
          .scale = first.scale,
          .read_rows = [name, load](std::size_t h0, std::size_t rows, std::span<float> out) {
            memory_training_grid(std::make_shared<const store::Grid>(load()), name).read_rows(h0, rows, out);
          }};
}

}  // namespace specula::acquire
