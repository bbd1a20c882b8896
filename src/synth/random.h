#pragma once

#include <cmath>
#include <cstdint>

namespace clutterseg::synth {

/// SplitMix64 finaliser: a bijective 64-bit mix with good avalanche.
inline uint64_t Mix64(uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// Counter-based hash of (seed, a, b, c): the same inputs give the same value on any thread.
inline uint64_t HashCounter(uint64_t seed, uint64_t a, uint64_t b = 0, uint64_t c = 0) {
  uint64_t h = Mix64(seed ^ 0x5851f42d4c957f2dULL);
  h = Mix64(h ^ a);
  h = Mix64(h ^ (b * 0x9e3779b97f4a7c15ULL));
  return Mix64(h ^ (c * 0xc2b2ae3d27d4eb4fULL));
}

/// Maps 64 random bits to [0, 1) with 53 bits of precision.
inline double ToUnit(uint64_t bits) { return static_cast<double>(bits >> 11) * 0x1.0p-53; }

/// A standard normal variate from two independent hashes (Box-Muller).
inline double GaussianFromBits(uint64_t bits1, uint64_t bits2) {
  const double u1 = 1.0 - ToUnit(bits1);  // (0, 1]
  const double u2 = ToUnit(bits2);
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2);
}

/// An approximately standard normal variate from one hash: the Irwin-Hall sum of four
/// 16-bit uniforms, centred and scaled to unit variance (support +-3.46). Far cheaper than
/// Box-Muller; good enough for lateral and colour noise.
inline double FastGaussianFromBits(uint64_t bits) {
  const uint64_t sum = (bits & 0xffffu) + ((bits >> 16) & 0xffffu) + ((bits >> 32) & 0xffffu) +
                       ((bits >> 48) & 0xffffu);
  // Each term is uniform on {0..65535}: mean 32767.5, variance (65536^2 - 1) / 12.
  constexpr double kMean = 4.0 * 32767.5;
  constexpr double kInvSigma = 1.0 / 37837.22723720648;
  return (static_cast<double>(sum) - kMean) * kInvSigma;
}

/// A small sequential generator (SplitMix64 stream) with portable distributions; unlike the
/// std:: distributions its output is identical across standard libraries.
class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(Mix64(seed)) {}

  uint64_t Next() {
    state_ += 0x9e3779b97f4a7c15ULL;
    uint64_t z = state_;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  /// Uniform in [lo, hi).
  double Uniform(double lo, double hi) { return lo + (hi - lo) * ToUnit(Next()); }
  /// Uniform integer in [lo, hi] (inclusive); lo <= hi.
  int UniformInt(int lo, int hi) {
    const uint64_t span = static_cast<uint64_t>(static_cast<int64_t>(hi) - lo + 1);
    return lo + static_cast<int>(Next() % span);
  }
  bool Bernoulli(double p) { return ToUnit(Next()) < p; }

 private:
  uint64_t state_;
};

}  // namespace clutterseg::synth
