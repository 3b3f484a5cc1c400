#pragma once
// Importing files into a store: each input's format told from its extension or contents (or given), read by the
// readers of store/io, masked, checked for NaN/Inf, resampled to a target grid when asked, and added to a writer's
// transaction. The public databases each layout comes from: docs/import.md.
#include <filesystem>
#include <string>
#include <vector>

#include "specula/core/wavelengths.h"
#include "specula/store/store.h"

namespace specula::store {

/// What NaN/Inf in valid pixels do: stop the import (one line naming the first) or mask those pixels.
enum class NanPolicy { reject, mask };

/// How import_files reads its inputs; empty members are decided from the files.
struct ImportOptions {
  std::string name;                   ///< object name when the inputs make one object (empty: from the file name)
  WavelengthGrid wavelengths;         ///< target grid the data is resampled onto; also the grid of data without one
  WavelengthGrid source_wavelengths;  ///< the grid of data without one, when `wavelengths` resamples
  std::string mask;                   ///< a PNG or one-band ENVI mask file; for .mat the mask variable
  std::string var;                    ///< the .mat variable (empty: detected, store/io/mat.h)
  std::string format = "auto";        ///< auto, envi, mat, png, exr, csv, brdf, usgs or ecostress
  NanPolicy nan = NanPolicy::reject;
  std::string units;                  ///< overrides the units the files give
  bool honour_bbl = true;             ///< drop the bands an ENVI bbl marks bad
};

/// What an import added ("imported image a: ...", one line per object) and what it noted on the way.
struct ImportReport {
  std::vector<std::string> imported;
  std::vector<std::string> notes;
};

/// The format of `path` ("envi", "mat", "png", "exr", "csv", "brdf", "usgs" or "ecostress") from its extension or,
/// for .txt, its first line; UsageError naming the file and asking for the `format` option otherwise.
std::string detect_import_format(const std::filesystem::path& path);

/// Reads every input (consecutive PNGs form one band stack, consecutive USGS/ECOSTRESS spectra one collection) and
/// adds its objects to `writer` without committing; InputError/UsageError naming the file and the option to set.
ImportReport import_files(StoreWriter& writer, const std::vector<std::filesystem::path>& inputs, const ImportOptions& options);

}  // namespace specula::store
