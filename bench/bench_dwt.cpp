// bench_dwt: DWT throughput of the de-noising step (paper Eq. 1).
//
// Work per repetition: wavedec (coif4, level 6, symmetric mode) of a 65536-sample random signal
// plus the reconstruction of d3 + d4 + d5 (waverecSelected), i.e. exactly what denoise() does.
// Throughput = input samples de-noised per second, best of 7 runs of 20 repetitions each
// (steady_clock). Also reports the time of a full RMSE-DMM basis selection over all 59
// candidate wavelets on a 240-sample (30 s at 8 Hz) volunteer displacement. Prints
//   BENCH dwt_throughput <samples/s> samples/s
//   BENCH dwt_basis_selection_time <ms> ms

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <random>
#include <vector>

#include "pedicle_drilling/core/breathing/denoising.hpp"
#include "pedicle_drilling/core/breathing/dwt.hpp"
#include "pedicle_drilling/core/breathing/virtual_volunteer.hpp"
#include "pedicle_drilling/core/breathing/wavelet.hpp"

int main() {
  namespace pd = pedicle_drilling::core;
  using Clock = std::chrono::steady_clock;
  constexpr std::size_t kLength = 65536;
  constexpr int kReps = 20;
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  std::vector<double> x(kLength);
  for (double& v : x) v = normal(rng);
  const pd::Wavelet& wavelet = pd::getWavelet("coif4");
  double best = 1e300;
  double checksum = 0.0;
  for (int run = 0; run < 7; ++run) {
    const auto start = Clock::now();
    for (int r = 0; r < kReps; ++r) {
      const pd::WaveletDecomposition dec =
          pd::wavedec(x, wavelet, 6, pd::ExtensionMode::kSymmetric);
      const std::vector<double> s = pd::waverecSelected(dec, {3, 4, 5}, false);
      checksum += s[kLength / 2];
    }
    best = std::min(best, std::chrono::duration<double>(Clock::now() - start).count());
  }
  std::printf("BENCH dwt_throughput %.4g samples/s\n", static_cast<double>(kLength) * kReps / best);

  const pd::PairedSamples p =
      pd::pairAtMarkerTimes(pd::generateVolunteer(pd::defaultVolunteer(1)).recording);
  double best_sel = 1e300;
  for (int run = 0; run < 5; ++run) {
    const auto start = Clock::now();
    const pd::DenoiseResult r = pd::selectAndDenoise(p.ap, p.tv);
    best_sel = std::min(best_sel, std::chrono::duration<double>(Clock::now() - start).count());
    checksum += r.denoised[0];
  }
  std::printf("BENCH dwt_basis_selection_time %.3f ms\n", best_sel * 1e3);
  std::fflush(stdout);
  std::fprintf(stderr, "# checksum %.6g\n", checksum);
  return 0;
}
