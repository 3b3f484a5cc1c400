// Streams every valid spectrum of a store through the block reader and reports throughput.
// Usage: block_reader_bench STORE.h5 [float|double] [repeats]
// Prints one JSON line: spectra, bytes (float32 payload), seconds (best of repeats), spectra_per_s,
// gb_per_s, threads, peak_rss_mb, checksum (sum of all values, to defeat dead-code elimination).
#include <fmt/format.h>
#include <omp.h>
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <string>

#include "specula/core/error.h"
#include "specula/store/block_reader.h"

using namespace specula;

template <class T>
double stream(const store::BlockReader& reader) {
  std::vector<double> sums(reader.block_count(), 0.0);
  store::for_each_block<T>(reader, [&](std::size_t i, const auto& m, int) { sums[i] = double(m.sum()); });
  double total = 0;
  for (double s : sums) total += s;
  return total;
}

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: block_reader_bench STORE.h5 [float|double] [repeats]\n");
    return 2;
  }
  try {
    const std::string type = argc > 2 ? argv[2] : "float";
    const int repeats = argc > 3 ? std::stoi(argv[3]) : 3;
    const store::Store s = store::Store::open(argv[1]);
    const store::BlockReader reader(s, {});
    double best = 1e300, checksum = 0;
    for (int r = 0; r < repeats; ++r) {
      const auto t0 = std::chrono::steady_clock::now();
      checksum = type == "double" ? stream<double>(reader) : stream<float>(reader);
      best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    }
    rusage ru{};
    getrusage(RUSAGE_SELF, &ru);
    const double bytes = double(reader.spectra()) * double(reader.bands()) * 4.0;
    fmt::print(
        R"({{"spectra":{},"bands":{},"blocks":{},"bytes":{},"seconds":{:.4f},"spectra_per_s":{:.0f},"gb_per_s":{:.3f},)"
        R"("threads":{},"type":"{}","peak_rss_mb":{:.1f},"checksum":{:.6e}}})"
        "\n",
        reader.spectra(), reader.bands(), reader.block_count(), bytes, best, double(reader.spectra()) / best,
        bytes / best / 1e9, omp_get_max_threads(), type, double(ru.ru_maxrss) / 1024.0, checksum);
  } catch (const Error& e) {
    std::fprintf(stderr, "block_reader_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
