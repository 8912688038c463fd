#include "pedicle_drilling/core/breathing/wavelet.hpp"

#include <map>
#include <stdexcept>

namespace pedicle_drilling::core {
namespace {

struct Registry {
  std::vector<Wavelet> wavelets;
  std::map<std::string, std::size_t> index;

  Registry() {
    std::size_t count = 0;
    const detail::RawWaveletFilters* table = detail::rawWaveletTable(&count);
    wavelets.reserve(count);
    for (std::size_t i = 0; i < count; ++i) {
      const detail::RawWaveletFilters& r = table[i];
      Wavelet w;
      w.name = r.name;
      w.family = r.family;
      w.orthogonal = r.orthogonal;
      w.dec_lo.assign(r.dec_lo, r.dec_lo + r.length);
      w.dec_hi.assign(r.dec_hi, r.dec_hi + r.length);
      w.rec_lo.assign(r.rec_lo, r.rec_lo + r.length);
      w.rec_hi.assign(r.rec_hi, r.rec_hi + r.length);
      index.emplace(w.name, wavelets.size());
      wavelets.push_back(std::move(w));
    }
  }
};

const Registry& registry() {
  static const Registry kRegistry;  // thread-safe initialisation (C++11 magic statics)
  return kRegistry;
}

}  // namespace

const Wavelet* findWavelet(const std::string& name) noexcept {
  const Registry& reg = registry();
  const auto it = reg.index.find(name);
  if (it == reg.index.end()) {
    return nullptr;
  }
  return &reg.wavelets[it->second];
}

const Wavelet& getWavelet(const std::string& name) {
  const Wavelet* w = findWavelet(name);
  if (w == nullptr) {
    throw std::invalid_argument("unknown wavelet '" + name +
                                "' (supported: db1-db20, sym2-sym20, coif1-coif5, bior1.1, "
                                "bior1.3, bior1.5, bior2.2, bior2.4, bior2.6, bior2.8, bior3.1, "
                                "bior3.3, bior3.5, bior3.7, bior3.9, bior4.4, bior5.5, bior6.8)");
  }
  return *w;
}

std::vector<std::string> allWaveletNames() {
  std::vector<std::string> names;
  for (const Wavelet& w : registry().wavelets) {
    names.push_back(w.name);
  }
  return names;
}

std::vector<std::string> waveletNames(WaveletFamily family) {
  std::vector<std::string> names;
  for (const Wavelet& w : registry().wavelets) {
    if (w.family == family) {
      names.push_back(w.name);
    }
  }
  return names;
}

}  // namespace pedicle_drilling::core
