#pragma once

#include <string>

namespace clutterseg::core {

/// True when `path` exists and is not a regular file: a FIFO, a device, a directory or a
/// socket. Readers check it before they open a path with stdio or liblcm, whose open of a
/// FIFO blocks until a writer comes (a hang, not an error). False when `path` does not exist
/// (the open then fails with its own message). Thread-safe.
bool IsNonRegularFile(const std::string& path);

}  // namespace clutterseg::core
