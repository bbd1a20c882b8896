#pragma once

#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

namespace clutterseg::testing {

/// Expects `fn()` to throw std::invalid_argument with `key` (a configuration key path such as
/// "segmenter.support.cell_px") in its message: a rejected parameter must say which one.
template <typename Fn>
void ExpectInvalidArgumentNaming(const Fn& fn, const std::string& key) {
  try {
    fn();
    ADD_FAILURE() << "no std::invalid_argument naming " << key;
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
  }
}

}  // namespace clutterseg::testing
