#pragma once
// What a store holds as JSON, the objects `specula info --json` prints, and the parts of `specula info`'s text that
// the store describes (docs/store-format.md).
#include <cstdint>
#include <nlohmann/json_fwd.hpp>
#include <string>

#include "specula/store/basis.h"
#include "specula/store/store.h"

namespace specula::store {

/// An image's description: kind, name, shape, wavelengths, units, valid pixels, chunking, provenance.
nlohmann::ordered_json image_json(const ImageInfo& info);
/// A collection's description: kind, name, size, bands, wavelengths, units, provenance.
nlohmann::ordered_json collection_json(const CollectionInfo& info);
/// A sample set's description: kind, name, size, bands, wavelengths, units, provenance.
nlohmann::ordered_json samples_json(const SamplesInfo& info);
/// A coefficient map's description: kind, name, image, basis, method, shape, k, valid pixels, provenance.
nlohmann::ordered_json coefficients_json(const CoefficientsInfo& info);
/// The basis `name`'s description: method, k, n, bands, wavelengths, source and how it was fit.
nlohmann::ordered_json basis_json(const std::string& name, const Basis& basis);
/// A BRDF grid's description: kind, name, bands, wavelengths, scale, units, compression, provenance and its source's
/// parameterisation (null, or its source, description, theta_i in radians, the ndf, sigma and vndf tables' height
/// and width and the sample grid's resolution).
nlohmann::ordered_json grid_json(const GridInfo& info);
/// A grid's parameterisation in one phrase: "none", or e.g. "source tables (RGL), 8 theta_i, ndf 128x2, vndf 128^2,
/// 32^2 sample grid".
std::string parameterisation_text(const GridInfo& info);
/// Every image, collection, sample set, grid, basis and coefficient map of `store`, one object each, in that order.
nlohmann::ordered_json objects_json(const Store& store);
/// Valid pixels over every image of the store.
std::uint64_t valid_spectra(const Store& store);
/// The store's path, format version, generation, size, creation time, valid spectra and objects_json().
nlohmann::ordered_json store_json(const Store& store);

}  // namespace specula::store
