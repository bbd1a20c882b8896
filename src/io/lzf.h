#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace clutterseg::io {

/// Largest factor by which a valid LZF stream can expand: a 3-byte back reference produces at
/// most 264 bytes. Used to reject declared sizes that no stream of a given length can reach.
inline constexpr size_t kLzfMaxExpansion = 88;

/// Compresses `size` bytes at `in` into the LZF format of liblzf (as used by PCD
/// `binary_compressed`) and replaces the contents of `out` (its capacity is reused).
/// The output is at most `size + size / 32 + 1` bytes. Deterministic; thread-safe (no shared
/// state). O(size).
void LzfCompress(const void* in, size_t size, std::vector<uint8_t>* out);

/// Decompresses the LZF stream `in[0, in_size)` into `out[0, out_capacity)`.
/// @returns the number of bytes decoded. Bytes of `out` past that count (within
/// `out_capacity`) may be overwritten too: the decoder copies in fixed-size chunks.
/// @throws std::runtime_error describing the defect when the stream is truncated, refers back
/// before the start of the output, or would write past `out_capacity`. Never reads or writes
/// out of bounds. Thread-safe. O(in_size + returned size).
size_t LzfDecompress(const void* in, size_t in_size, void* out, size_t out_capacity);

}  // namespace clutterseg::io
