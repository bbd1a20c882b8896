#include "clutterseg/io/lzf.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

namespace clutterseg::io {
namespace {

std::vector<uint8_t> RoundTrip(const std::vector<uint8_t>& input, size_t* compressed_size) {
  std::vector<uint8_t> packed;
  LzfCompress(input.data(), input.size(), &packed);
  EXPECT_LE(packed.size(), input.size() + input.size() / 32 + 1);
  *compressed_size = packed.size();
  std::vector<uint8_t> output(input.size());
  const size_t n = LzfDecompress(packed.data(), packed.size(), output.data(), output.size());
  EXPECT_EQ(n, input.size());
  return output;
}

TEST(LzfTest, RandomDataRoundTripsAtManySizes) {
  std::mt19937 rng(12345);
  for (size_t size : {0u, 1u, 2u, 3u, 4u, 31u, 32u, 33u, 64u, 65u, 1000u, 8193u, 1u << 20}) {
    std::vector<uint8_t> input(size);
    for (uint8_t& b : input) b = static_cast<uint8_t>(rng());
    size_t packed = 0;
    EXPECT_EQ(RoundTrip(input, &packed), input) << "size " << size;
  }
}

TEST(LzfTest, RepetitiveDataRoundTripsAndCompresses) {
  // Long zero runs (longer than the 264-byte maximum match), short periodic patterns, text,
  // and matches at the 8192-byte maximum offset.
  std::vector<uint8_t> input(1 << 20, 0);
  for (size_t i = 300000; i < 600000; ++i) input[i] = static_cast<uint8_t>(i % 7);
  const std::string text = "the quick brown fox jumps over the lazy dog; ";
  for (size_t i = 600000; i < 700000; ++i) input[i] = static_cast<uint8_t>(text[i % text.size()]);
  std::mt19937 rng(7);
  std::vector<uint8_t> block(8192);
  for (uint8_t& b : block) b = static_cast<uint8_t>(rng());
  for (size_t i = 700000; i < 700000 + 4 * block.size(); ++i) input[i] = block[i % block.size()];
  size_t packed = 0;
  EXPECT_EQ(RoundTrip(input, &packed), input);
  EXPECT_LT(packed, input.size() / 20) << "repetitive data should compress well";
}

TEST(LzfTest, EveryShortPeriodRoundTrips) {
  // Periods below and above the 8- and 16-byte copy widths of the decoder, with the match
  // running up to the very end of the output buffer.
  std::mt19937 rng(99);
  for (size_t period = 1; period <= 40; ++period) {
    for (size_t size : {period + 3, period + 40, size_t{3000}}) {
      std::vector<uint8_t> input(size);
      for (size_t i = 0; i < period && i < size; ++i) input[i] = static_cast<uint8_t>(rng());
      for (size_t i = period; i < size; ++i) input[i] = input[i - period];
      size_t packed = 0;
      EXPECT_EQ(RoundTrip(input, &packed), input) << "period " << period << " size " << size;
    }
  }
}

TEST(LzfTest, ShortPeriodRunsAmidRandomDataRoundTrip) {
  // Runs of periods 1-7 and of every length up to the longest back reference, between random
  // bytes, so that they are decoded in the middle of a long stream (not near its ends).
  std::mt19937 rng(7);
  std::vector<uint8_t> input;
  for (int run = 0; run < 3000; ++run) {
    const size_t gap = rng() % 40;
    for (size_t i = 0; i < gap; ++i) input.push_back(static_cast<uint8_t>(rng()));
    const size_t period = 1 + rng() % 7;
    const size_t length = period + 3 + rng() % 300;
    for (size_t i = 0; i < period; ++i) input.push_back(static_cast<uint8_t>(rng()));
    for (size_t i = period; i < length; ++i) input.push_back(input[input.size() - period]);
  }
  size_t packed = 0;
  EXPECT_EQ(RoundTrip(input, &packed), input);
  EXPECT_LT(packed, input.size() / 2);
}

TEST(LzfTest, FloatPlanesLikePcdRoundTrip) {
  std::vector<float> values(640 * 480);
  for (size_t i = 0; i < values.size(); ++i) {
    values[i] = (i % 5 == 0) ? std::numeric_limits<float>::quiet_NaN()
                             : 0.5f + 0.001f * static_cast<float>(i % 640);
  }
  std::vector<uint8_t> input(values.size() * 4);
  std::memcpy(input.data(), values.data(), input.size());
  size_t packed = 0;
  EXPECT_EQ(RoundTrip(input, &packed), input);
}

TEST(LzfTest, DecodesHandWrittenStream) {
  // Literal "abc", back reference of 3 at distance 3, then 7+1+2 = 10 copies of the last byte
  // (length code 7 with an extra length byte), then literal "Z".
  const std::vector<uint8_t> stream = {0x02, 'a',  'b',  'c',  0x20, 0x02,
                                       0xe0, 0x01, 0x00, 0x00, 'Z'};
  std::vector<uint8_t> out(32);
  const size_t n = LzfDecompress(stream.data(), stream.size(), out.data(), out.size());
  EXPECT_EQ(std::string(out.begin(), out.begin() + static_cast<long>(n)),
            "abcabc" + std::string(10, 'c') + "Z");
}

TEST(LzfTest, RejectsBackReferenceBeforeStart) {
  const std::vector<uint8_t> stream = {0x00, 'a', 0x20, 0x05};  // distance 6 with 1 byte written
  std::vector<uint8_t> out(16);
  EXPECT_THROW(LzfDecompress(stream.data(), stream.size(), out.data(), out.size()),
               std::runtime_error);
}

TEST(LzfTest, RejectsTruncatedStreams) {
  std::vector<uint8_t> out(64);
  const std::vector<uint8_t> literal = {0x05, 'a', 'b'};  // promises 6 literal bytes
  EXPECT_THROW(LzfDecompress(literal.data(), literal.size(), out.data(), out.size()),
               std::runtime_error);
  const std::vector<uint8_t> backref = {0x00, 'a', 0x20};  // missing the offset byte
  EXPECT_THROW(LzfDecompress(backref.data(), backref.size(), out.data(), out.size()),
               std::runtime_error);
  const std::vector<uint8_t> long_backref = {0x00, 'a', 0xe0};  // missing the length byte
  EXPECT_THROW(LzfDecompress(long_backref.data(), long_backref.size(), out.data(), out.size()),
               std::runtime_error);
}

TEST(LzfTest, RejectsOutputOverrun) {
  std::vector<uint8_t> input(1000, 42);
  std::vector<uint8_t> packed;
  LzfCompress(input.data(), input.size(), &packed);
  std::vector<uint8_t> out(999);
  try {
    LzfDecompress(packed.data(), packed.size(), out.data(), out.size());
    FAIL() << "expected an overrun error";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("overruns"), std::string::npos) << e.what();
  }
}

TEST(LzfTest, ReusesOutputBuffer) {
  std::vector<uint8_t> packed(5, 0xaa);
  const std::vector<uint8_t> input = {1, 2, 3};
  LzfCompress(input.data(), input.size(), &packed);
  EXPECT_EQ(packed, (std::vector<uint8_t>{0x02, 1, 2, 3}));
}

}  // namespace
}  // namespace clutterseg::io
