#pragma once
// Neural BRDF weights of Sztrajman et al. 2021 ("Neural BRDF Representation and Importance Sampling") as Keras
// writes them to HDF5: groups dense_1, dense_2, dense_3, each holding dense_N/kernel:0 (in x out) and
// dense_N/bias:0 (out), float32, for a 6 -> 21 -> 21 -> 3 multilayer perceptron.
#include <filesystem>
#include <vector>

namespace specula::store {

/// The weights of one NBRDF network, row-major as Keras stores them (kernel[i * out + o] for input i, output o).
struct NbrdfWeights {
  static constexpr int kInputs = 6, kHidden = 21, kOutputs = 3;
  std::vector<float> kernel1, bias1;  ///< 6 x 21, 21
  std::vector<float> kernel2, bias2;  ///< 21 x 21, 21
  std::vector<float> kernel3, bias3;  ///< 21 x 3, 3
};

/// True when `path` is an HDF5 file holding a group dense_1 (an NBRDF candidate); false for anything else.
bool is_nbrdf(const std::filesystem::path& path);
/// Reads the weights; throws InputError naming the file and the dataset for anything else: not HDF5, a layer
/// missing, a kernel or bias of the wrong shape (found and expected), a NaN or infinite weight.
NbrdfWeights read_nbrdf(const std::filesystem::path& path);

}  // namespace specula::store
