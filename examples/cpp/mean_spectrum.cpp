// Opens a specula store, streams every valid spectrum of its images in blocks and prints their mean, one
// "wavelength value" line per band. Usage: mean_spectrum STORE.h5 [IMAGE_GLOB...]
#include <cstdio>
#include <exception>
#include <vector>

#include <Eigen/Core>

#include "specula/store/block_reader.h"
#include "specula/version.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s STORE.h5 [IMAGE_GLOB...]   (specula %s)\n", argv[0], SPECULA_VERSION);
    return 2;
  }
  try {
    const auto store = specula::store::Store::open(argv[1]);
    specula::store::Selection selection;
    for (int i = 2; i < argc; ++i) selection.image_globs.emplace_back(argv[i]);
    const specula::store::BlockReader reader(store, selection);

    // One partial sum per block, added in block order: the mean does not depend on the thread count.
    std::vector<Eigen::VectorXd> sums(reader.block_count());
    specula::store::for_each_block<double>(reader, [&](std::size_t block, const auto& spectra, int /*thread*/) {
      sums[block] = spectra.colwise().sum().transpose();
    });
    Eigen::VectorXd mean = Eigen::VectorXd::Zero(Eigen::Index(reader.bands()));
    for (const auto& s : sums)
      if (s.size() > 0) mean += s;
    mean /= double(reader.spectra());

    std::printf("# %llu spectra, %s\n", static_cast<unsigned long long>(reader.spectra()), reader.units().c_str());
    for (std::size_t b = 0; b < reader.bands(); ++b)
      std::printf("%g %.9g\n", reader.wavelengths()[b], mean[Eigen::Index(b)]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
  return 0;
}
