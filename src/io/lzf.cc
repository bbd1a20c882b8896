#include "clutterseg/io/lzf.h"

#include <algorithm>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

namespace clutterseg::io {
namespace {

constexpr int kHashBits = 14;
constexpr size_t kHashSize = size_t{1} << kHashBits;
constexpr size_t kNoEntry = std::numeric_limits<size_t>::max();
constexpr size_t kMaxLiteralRun = 32;  // control bytes 0..31 encode runs of 1..32 bytes
constexpr size_t kMaxOffset = 8192;    // 13 bits of offset, stored minus one
constexpr size_t kMinMatch = 3;
constexpr size_t kMaxMatch = 7 + 255 + 2;
constexpr size_t kChunk = 16;  // bytes per step of the fast back-reference copy

inline uint32_t HashAt(const uint8_t* p) {
  const uint32_t v = (uint32_t{p[0]} << 16) | (uint32_t{p[1]} << 8) | uint32_t{p[2]};
  return (v * 2654435761u) >> (32 - kHashBits);
}

[[noreturn]] void Corrupt(const std::string& what, size_t input_offset) {
  throw std::runtime_error("corrupt LZF stream: " + what + " (at compressed byte " +
                           std::to_string(input_offset) + ")");
}

}  // namespace

void LzfCompress(const void* in_bytes, size_t size, std::vector<uint8_t>* out) {
  const uint8_t* in = static_cast<const uint8_t*>(in_bytes);
  out->clear();
  out->reserve(size + size / kMaxLiteralRun + 1);
  if (size == 0) return;

  std::vector<size_t> table(kHashSize, kNoEntry);
  size_t literal_start = 0;
  auto flush_literals = [&](size_t end) {
    while (literal_start < end) {
      const size_t run = std::min(kMaxLiteralRun, end - literal_start);
      out->push_back(static_cast<uint8_t>(run - 1));
      out->insert(out->end(), in + literal_start, in + literal_start + run);
      literal_start += run;
    }
  };

  size_t ip = 0;
  while (ip + kMinMatch <= size) {
    const uint32_t h = HashAt(in + ip);
    const size_t ref = table[h];
    table[h] = ip;
    if (ref == kNoEntry || ip - ref > kMaxOffset || in[ref] != in[ip] ||
        in[ref + 1] != in[ip + 1] || in[ref + 2] != in[ip + 2]) {
      ++ip;
      continue;
    }
    const size_t max_len = std::min(kMaxMatch, size - ip);
    size_t len = kMinMatch;
    while (len < max_len && in[ref + len] == in[ip + len]) ++len;

    flush_literals(ip);
    const size_t offset = ip - ref - 1;
    const size_t coded_len = len - 2;
    if (coded_len < 7) {
      out->push_back(static_cast<uint8_t>((coded_len << 5) | (offset >> 8)));
    } else {
      out->push_back(static_cast<uint8_t>((7u << 5) | (offset >> 8)));
      out->push_back(static_cast<uint8_t>(coded_len - 7));
    }
    out->push_back(static_cast<uint8_t>(offset & 0xff));

    const size_t end = ip + len;
    for (size_t k = ip + 1; k < end && k + kMinMatch <= size; ++k) table[HashAt(in + k)] = k;
    ip = end;
    literal_start = ip;
  }
  flush_literals(size);
}

namespace {

template <size_t N>
inline void Copy(uint8_t* dst, const uint8_t* src) {
  std::memcpy(dst, src, N);
}

// Decodes tokens while the next one cannot reach either end: the input holds a control byte
// plus a full 32-byte literal run, and the output room for the longest back reference plus
// the surplus of the chunked copies. Only the back-reference distance needs a check there.
// Stops before a distance pointing before the start, which the checked decoder reports;
// *ip_io and *op_io are advanced past the decoded tokens.
void DecodeFast(const uint8_t* in, size_t in_size, uint8_t* out, size_t out_capacity, size_t* ip_io,
                size_t* op_io) {
  constexpr size_t kInSlack = 1 + kMaxLiteralRun + 2;
  constexpr size_t kOutSlack = kMaxMatch + kChunk;
  if (in_size < kInSlack || out_capacity < kOutSlack) return;
  const uint8_t* ip = in + *ip_io;
  uint8_t* op = out + *op_io;
  const uint8_t* const ip_end = in + (in_size - kInSlack);
  const uint8_t* const op_end = out + (out_capacity - kOutSlack);
  while (ip < ip_end && op < op_end) {
    const unsigned ctrl = *ip++;
    if (ctrl < kMaxLiteralRun) {
      // Fixed 32-byte copy; the surplus past the run is overwritten later.
      Copy<2 * kChunk>(op, ip);
      ip += ctrl + 1;
      op += ctrl + 1;
      continue;
    }
    size_t len = ctrl >> 5;
    if (len == 7) len += *ip++;
    const size_t offset = ((size_t{ctrl & 31u} << 8) | *ip++) + 1;
    len += 2;
    if (offset > static_cast<size_t>(op - out)) {
      ip -= len >= 9 ? 3 : 2;  // back to the control byte
      break;
    }
    const uint8_t* ref = op - offset;
    // 8-byte chunks never overlap their source at a distance of 8 or more; the surplus past
    // `len` is overwritten later. The first 32 bytes (all of nearly every reference) are
    // copied without a branch on the length, the kind of branch that mispredicts here.
    if (offset >= 8) {
      Copy<8>(op, ref);
      Copy<8>(op + 8, ref + 8);
      Copy<8>(op + 16, ref + 16);
      Copy<8>(op + 24, ref + 24);
      for (size_t k = 32; k < len; k += 8) Copy<8>(op + k, ref + k);
    } else if ((offset & (offset - 1)) == 0) {
      // Periods 1, 2 and 4 (runs of a byte, of 16-bit values, of one float, e.g. NaN fields):
      // one 8-byte pattern stored over and over. A byte loop here would wait on its own
      // stores at every step.
      uint64_t head;
      Copy<8>(reinterpret_cast<uint8_t*>(&head), ref);  // bytes past the period are unused
      const uint64_t mask = (uint64_t{1} << (8 * offset)) - 1;
      const uint64_t pattern = (head & mask) * (~uint64_t{0} / mask);
      for (size_t k = 0; k < len; k += 8)
        Copy<8>(op + k, reinterpret_cast<const uint8_t*>(&pattern));
    } else {
      for (size_t k = 0; k < len; ++k) op[k] = ref[k];
    }
    op += len;
  }
  *ip_io = static_cast<size_t>(ip - in);
  *op_io = static_cast<size_t>(op - out);
}

}  // namespace

size_t LzfDecompress(const void* in_bytes, size_t in_size, void* out_bytes, size_t out_capacity) {
  const uint8_t* const in = static_cast<const uint8_t*>(in_bytes);
  uint8_t* const out = static_cast<uint8_t*>(out_bytes);
  size_t ip = 0;
  size_t op = 0;
  // The bulk of the stream, then its last tokens (and any error) with every check.
  DecodeFast(in, in_size, out, out_capacity, &ip, &op);
  while (ip < in_size) {
    const size_t token_start = ip;
    const unsigned ctrl = in[ip++];
    if (ctrl < kMaxLiteralRun) {
      const size_t len = ctrl + 1;
      if (in_size - ip < len) {
        Corrupt("literal run of " + std::to_string(len) + " bytes runs past the end of the stream",
                token_start);
      }
      if (out_capacity - op < len) {
        Corrupt(
            "literal run overruns the output buffer of " + std::to_string(out_capacity) + " bytes",
            token_start);
      }
      if (in_size - ip >= kMaxLiteralRun && out_capacity - op >= kMaxLiteralRun) {
        // Fixed-size copy (compiles to two vector moves); the surplus is overwritten later.
        std::memcpy(out + op, in + ip, kMaxLiteralRun);
      } else {
        std::memcpy(out + op, in + ip, len);
      }
      ip += len;
      op += len;
      continue;
    }
    size_t len = ctrl >> 5;
    if (len == 7) {
      if (ip >= in_size) Corrupt("stream ends inside a back reference", token_start);
      len += in[ip++];
    }
    if (ip >= in_size) Corrupt("stream ends inside a back reference", token_start);
    const size_t offset = ((size_t{ctrl & 31u} << 8) | in[ip++]) + 1;
    len += 2;
    if (offset > op) {
      Corrupt("back reference " + std::to_string(offset) + " bytes behind output position " +
                  std::to_string(op) + " points before the start",
              token_start);
    }
    if (out_capacity - op < len) {
      Corrupt(
          "back reference overruns the output buffer of " + std::to_string(out_capacity) + " bytes",
          token_start);
    }
    const uint8_t* ref = out + op - offset;
    if (offset >= kChunk && out_capacity - op >= len + kChunk) {
      // Fixed-size chunks never overlap their source when offset >= kChunk; the surplus past
      // `len` is overwritten later.
      for (size_t k = 0; k < len; k += kChunk) std::memcpy(out + op + k, ref + k, kChunk);
    } else if (offset >= 8 && out_capacity - op >= len + 8) {
      for (size_t k = 0; k < len; k += 8) std::memcpy(out + op + k, ref + k, 8);
    } else if (len <= kChunk) {
      for (size_t k = 0; k < len; ++k) out[op + k] = ref[k];
    } else if (offset >= len) {
      std::memcpy(out + op, ref, len);
    } else if (offset == 1) {
      std::memset(out + op, *ref, len);
    } else {
      // Overlapping copy of a pattern with period `offset`. After k bytes (a multiple of the
      // period) the source [ref, out + op + k) holds offset + k periodic bytes, so the next
      // non-overlapping chunk can be that long: the chunk size doubles each step.
      size_t k = 0;
      while (k < len) {
        const size_t chunk = std::min(offset + k, len - k);
        std::memcpy(out + op + k, ref, chunk);
        k += chunk;
      }
    }
    op += len;
  }
  return op;
}

}  // namespace clutterseg::io
