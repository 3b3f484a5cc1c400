#pragma once
// Importing files into a store: each input's format told from its extension or contents (or given), read by the
// readers of store/io, masked, checked for NaN/Inf, resampled to a target grid when asked, and added to a writer's
// transaction. Directories and glob patterns expand to every file they hold; files no reader recognises are skipped
// and reported. Files are read in parallel within a memory budget and added in input order, so the store's content
// does not depend on the number of jobs. The public databases each layout comes from: docs/import.md.
#include <cstdint>
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
  std::string format = "auto";        ///< auto, envi, mat, png, exr, csv, brdf, usgs, ecostress or gdal
  NanPolicy nan = NanPolicy::reject;
  std::string units;       ///< overrides the units the files give
  bool honour_bbl = true;  ///< drop the bands an ENVI bbl marks bad
  bool strict = false;     ///< a file skipped in a directory or glob is an error (nothing is imported)
  unsigned jobs = 1;       ///< files read at once, at most (also at most the OpenMP threads)
  std::uint64_t memory_budget = std::uint64_t{1} << 30;  ///< bytes the files read at once may take, estimated from
                                                         ///< their headers; a file larger than this is read alone
  std::uint64_t strip_bytes = std::uint64_t{32} << 20;   ///< bytes of rows a streamed (GDAL) raster reads at once
};

/// What an import added ("imported image a: ...", one line per object) and what it noted on the way.
struct ImportReport {
  std::vector<std::string> imported;
  std::vector<std::string> notes;
  std::vector<std::string> skipped;  ///< one line per file a directory or glob held that was not imported, and why
};

/// The files the inputs stand for: each directory or glob pattern (expanded here with glob(3)) walked in name order.
struct ImportInputs {
  std::vector<std::filesystem::path> files;  ///< files, and directories that are PNG band stacks
  std::vector<std::string> skipped;          ///< "PATH: skipped: WHY" per file found but not recognised
};

/// Expands `inputs`: a named file stays as it is; a directory holding PNGs and no other recognised file is one band
/// stack; any other directory, and every match of a pattern with * ? or [ that names no existing file, contributes
/// each file it holds that a reader recognises (ENVI data files through their .hdr; a pattern's PNGs as if named)
/// and a skip line for the rest.
/// InputError when a pattern matches nothing.
ImportInputs expand_import_inputs(const std::vector<std::filesystem::path>& inputs, const ImportOptions& options);

/// The format of `path` ("envi", "mat", "png", "exr", "csv", "brdf", "usgs", "ecostress" or "gdal" for .tif/.tiff)
/// from its extension or, for .txt, its first line; UsageError naming the file and asking for the `format` option.
std::string detect_import_format(const std::filesystem::path& path);

/// Reads every input as expand_import_inputs finds them (consecutive PNG files form one band stack, consecutive
/// USGS/ECOSTRESS spectra one collection) and adds its objects to `writer` in input order without committing; GDAL
/// rasters are streamed by row strips. InputError/UsageError naming the file and the option to set, also for a skip
/// when `strict`; with several failures, the first input's.
ImportReport import_files(StoreWriter& writer, const std::vector<std::filesystem::path>& inputs,
                          const ImportOptions& options);

}  // namespace specula::store
