#pragma once
// The tables of a learned BRDF prior (acquire/prior.h) as the store keeps them: the "priors" object kind
// (docs/store-format.md). Written by StoreWriter::add_prior, read by Store::read_prior.
#include <string>
#include <vector>

namespace specula::store {

struct PriorTables {
  std::vector<double> wavelengths;  ///< the training grids' bands (nm)
  std::vector<double> knots;        ///< channel knot wavelengths (nm)
  std::vector<double> variances;    ///< k
  double epsilon = 0;
  std::vector<float> reference;       ///< one value per cell
  std::vector<float> mean;            ///< one value per cell
  std::vector<float> components;      ///< k x cells, row-major
  std::vector<std::string> training;  ///< the training grids, one name per material
};

}  // namespace specula::store
