#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

namespace clutterseg::geometry {

/// An open-addressing (linear probing) hash map from 64-bit keys to 32-bit indices, for the
/// voxel and seed-cell lookups of one frame. Clear() keeps the storage, so a map reused across
/// frames allocates only when a frame needs more slots than any before it.
/// The key ~0 is reserved. Not thread-safe for writes; concurrent Find() calls are fine.
class KeyIndexMap {
 public:
  static constexpr uint64_t kEmptyKey = ~uint64_t{0};
  static constexpr uint32_t kNotFound = ~uint32_t{0};

  /// Empties the map and makes room for `expected` entries at a load factor of at most 1/2.
  void Clear(size_t expected) {
    size_t capacity = 1024;
    int bits = 10;
    while (capacity < 2 * expected) {
      capacity <<= 1;
      ++bits;
    }
    // Never shrink: a table sized for the largest frame so far costs only its clearing, and a
    // smaller one would have to grow (allocate) again on the next large frame.
    if (capacity < keys_.size()) {
      capacity = keys_.size();
      bits = bits_;
    }
    if (capacity != keys_.size()) {
      keys_.assign(capacity, kEmptyKey);
      values_.resize(capacity);
      bits_ = bits;
    } else {
      std::fill(keys_.begin(), keys_.end(), kEmptyKey);
    }
    size_ = 0;
  }

  size_t size() const { return size_; }

  /// Returns the value stored for `key`, inserting `value` for it when absent (`*inserted`
  /// says which). Grows (rehashing) when the load would exceed 1/2.
  uint32_t FindOrInsert(uint64_t key, uint32_t value, bool* inserted) {
    if (2 * (size_ + 1) > keys_.size()) Grow();
    const size_t mask = keys_.size() - 1;
    size_t slot = Hash(key);
    for (;;) {
      const uint64_t k = keys_[slot];
      if (k == key) {
        *inserted = false;
        return values_[slot];
      }
      if (k == kEmptyKey) {
        keys_[slot] = key;
        values_[slot] = value;
        ++size_;
        *inserted = true;
        return value;
      }
      slot = (slot + 1) & mask;
    }
  }

  /// Value stored for `key`, or kNotFound.
  uint32_t Find(uint64_t key) const {
    const size_t mask = keys_.size() - 1;
    size_t slot = Hash(key);
    for (;;) {
      const uint64_t k = keys_[slot];
      if (k == key) return values_[slot];
      if (k == kEmptyKey) return kNotFound;
      slot = (slot + 1) & mask;
    }
  }

 private:
  size_t Hash(uint64_t key) const {
    return static_cast<size_t>((key * 0x9E3779B97F4A7C15ull) >> (64 - bits_));
  }

  void Grow() {
    std::vector<uint64_t> old_keys;
    std::vector<uint32_t> old_values;
    old_keys.swap(keys_);
    old_values.swap(values_);
    const size_t capacity = old_keys.empty() ? 1024 : old_keys.size() * 2;
    int bits = 0;
    while ((size_t{1} << bits) < capacity) ++bits;
    keys_.assign(capacity, kEmptyKey);
    values_.resize(capacity);
    bits_ = bits;
    size_ = 0;
    bool inserted = false;
    for (size_t s = 0; s < old_keys.size(); ++s) {
      if (old_keys[s] != kEmptyKey) FindOrInsert(old_keys[s], old_values[s], &inserted);
    }
  }

  std::vector<uint64_t> keys_;
  std::vector<uint32_t> values_;
  int bits_{10};
  size_t size_{0};
};

}  // namespace clutterseg::geometry
