#pragma once

#include <string_view>

#include "clutterseg/core/types.h"

namespace clutterseg::core {

/// Natural ("human") order of file names: runs of digits compare as numbers, so learn2 sorts
/// before learn10; equal numbers with fewer leading zeros come first. A strict weak order.
bool NaturalLess(std::string_view a, std::string_view b);

/// HSV to 8-bit RGB; hue in turns (wraps, 0 = red), saturation and value in 0..1.
Rgb8 HsvToRgb(double hue, double saturation, double value);

}  // namespace clutterseg::core
