#include "clutterseg/core/file_kind.h"

#include <sys/stat.h>

namespace clutterseg::core {

bool IsNonRegularFile(const std::string& path) {
  struct stat st {};
  return stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode);
}

}  // namespace clutterseg::core
