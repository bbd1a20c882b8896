#pragma once

#include <string_view>

#include "clutterseg/core/types.h"

namespace clutterseg::core {

/// Natural ("human") order of file names: runs of digits compare as numbers, so learn2 sorts
/// before learn10; equal numbers with fewer leading zeros come first. A strict weak order.
bool NaturalLess(std::string_view a, std::string_view b);

/// True when the file name `name` ends in `extension` (e.g. ".pcd"), ignoring ASCII case:
/// FRAME.PCD and frame.Pcd are PCD files too.
bool HasExtension(std::string_view name, std::string_view extension);

/// The index of the first control character (bytes 0x00-0x1f and 0x7f: NUL, newline, ...) of
/// `text`, or -1 when it has none. Names published in messages (camera and frame names) must
/// have none: LCM encodes strings up to their first NUL.
int FirstControlCharacter(std::string_view text);

/// HSV to 8-bit RGB; hue in turns (wraps, 0 = red), saturation and value in 0..1.
Rgb8 HsvToRgb(double hue, double saturation, double value);

}  // namespace clutterseg::core
