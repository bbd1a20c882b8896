#pragma once

// Runs the clutterseg-synth executable from the tests (CLUTTERSEG_SYNTH_TOOL is its path).

#include <cstdlib>
#include <string>

#include <sys/wait.h>

namespace clutterseg::synth::testutil {

/// Runs the tool with `args` (output discarded) and returns its exit code, -1 if it crashed.
inline int RunSynthTool(const std::string& args) {
  const std::string cmd = std::string(CLUTTERSEG_SYNTH_TOOL) + " " + args + " >/dev/null 2>&1";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace clutterseg::synth::testutil
