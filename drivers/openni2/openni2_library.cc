// libOpenNI2 loaded at run time (dlopen) rather than linked, so that a process can choose which
// copy of the driver directory OpenNI2 scans: OpenNI2 loads every driver in
// `OpenNI2/Drivers` beside the path it was itself loaded from. A replay needs only OniFile;
// the camera drivers start USB threads that make OpenNI::shutdown() take 0.25-0.5 s.
//
// The C functions of OniCAPI.h that OpenNI.h's inline C++ classes call are defined here and
// forward to the loaded library. A call before any InitializeOpenNI2() loads the library with
// all its drivers, as linking it would have.

#include "clutterseg/drivers/openni2/openni2_library.h"

#include <OniCAPI.h>
#include <dlfcn.h>

#include <atomic>
#include <filesystem>
#include <mutex>

// Every C function of OniCAPI.h this project uses: X(return type, name, (parameters),
// (arguments), value returned when the library cannot be loaded).
#define CLUTTERSEG_ONI_FUNCTIONS(X)                                                              \
  X(OniStatus, oniInitialize, (int api_version), (api_version), ONI_STATUS_ERROR)                \
  X(void, oniShutdown, (), (), )                                                                 \
  X(OniStatus, oniGetDeviceList, (OniDeviceInfo * *devices, int* count), (devices, count),       \
    ONI_STATUS_ERROR)                                                                            \
  X(OniStatus, oniReleaseDeviceList, (OniDeviceInfo * devices), (devices), ONI_STATUS_ERROR)     \
  X(OniStatus, oniRegisterDeviceCallbacks,                                                       \
    (OniDeviceCallbacks * callbacks, void* cookie, OniCallbackHandle* handle),                   \
    (callbacks, cookie, handle), ONI_STATUS_ERROR)                                               \
  X(void, oniUnregisterDeviceCallbacks, (OniCallbackHandle handle), (handle), )                  \
  X(OniStatus, oniWaitForAnyStream,                                                              \
    (OniStreamHandle * streams, int num_streams, int* stream_index, int timeout),                \
    (streams, num_streams, stream_index, timeout), ONI_STATUS_ERROR)                             \
  X(const char*, oniGetExtendedError, (), (), "libOpenNI2 could not be loaded")                  \
  X(OniStatus, oniDeviceOpen, (const char* uri, OniDeviceHandle* device), (uri, device),         \
    ONI_STATUS_ERROR)                                                                            \
  X(OniStatus, oniDeviceClose, (OniDeviceHandle device), (device), ONI_STATUS_ERROR)             \
  X(const OniSensorInfo*, oniDeviceGetSensorInfo, (OniDeviceHandle device, OniSensorType type),  \
    (device, type), nullptr)                                                                     \
  X(OniStatus, oniDeviceGetInfo, (OniDeviceHandle device, OniDeviceInfo * info), (device, info), \
    ONI_STATUS_ERROR)                                                                            \
  X(OniStatus, oniDeviceCreateStream,                                                            \
    (OniDeviceHandle device, OniSensorType type, OniStreamHandle * stream),                      \
    (device, type, stream), ONI_STATUS_ERROR)                                                    \
  X(OniStatus, oniDeviceEnableDepthColorSync, (OniDeviceHandle device), (device),                \
    ONI_STATUS_ERROR)                                                                            \
  X(OniStatus, oniDeviceSetProperty,                                                             \
    (OniDeviceHandle device, int property_id, const void* data, int size),                       \
    (device, property_id, data, size), ONI_STATUS_ERROR)                                         \
  X(OniStatus, oniDeviceGetProperty,                                                             \
    (OniDeviceHandle device, int property_id, void* data, int* size),                            \
    (device, property_id, data, size), ONI_STATUS_ERROR)                                         \
  X(OniBool, oniDeviceIsPropertySupported, (OniDeviceHandle device, int property_id),            \
    (device, property_id), FALSE)                                                                \
  X(OniBool, oniDeviceIsCommandSupported, (OniDeviceHandle device, int command_id),              \
    (device, command_id), FALSE)                                                                 \
  X(OniBool, oniDeviceIsImageRegistrationModeSupported,                                          \
    (OniDeviceHandle device, OniImageRegistrationMode mode), (device, mode), FALSE)              \
  X(void, oniStreamDestroy, (OniStreamHandle stream), (stream), )                                \
  X(const OniSensorInfo*, oniStreamGetSensorInfo, (OniStreamHandle stream), (stream), nullptr)   \
  X(OniStatus, oniStreamStart, (OniStreamHandle stream), (stream), ONI_STATUS_ERROR)             \
  X(void, oniStreamStop, (OniStreamHandle stream), (stream), )                                   \
  X(OniStatus, oniStreamReadFrame, (OniStreamHandle stream, OniFrame * *frame), (stream, frame), \
    ONI_STATUS_ERROR)                                                                            \
  X(OniStatus, oniStreamSetProperty,                                                             \
    (OniStreamHandle stream, int property_id, const void* data, int size),                       \
    (stream, property_id, data, size), ONI_STATUS_ERROR)                                         \
  X(OniStatus, oniStreamGetProperty,                                                             \
    (OniStreamHandle stream, int property_id, void* data, int* size),                            \
    (stream, property_id, data, size), ONI_STATUS_ERROR)                                         \
  X(OniBool, oniStreamIsPropertySupported, (OniStreamHandle stream, int property_id),            \
    (stream, property_id), FALSE)                                                                \
  X(void, oniFrameRelease, (OniFrame * frame), (frame), )                                        \
  X(void, oniFrameAddRef, (OniFrame * frame), (frame), )                                         \
  X(OniStatus, oniCreateRecorder, (const char* file_name, OniRecorderHandle* recorder),          \
    (file_name, recorder), ONI_STATUS_ERROR)                                                     \
  X(OniStatus, oniRecorderAttachStream,                                                          \
    (OniRecorderHandle recorder, OniStreamHandle stream, OniBool lossy),                         \
    (recorder, stream, lossy), ONI_STATUS_ERROR)                                                 \
  X(OniStatus, oniRecorderStart, (OniRecorderHandle recorder), (recorder), ONI_STATUS_ERROR)     \
  X(void, oniRecorderStop, (OniRecorderHandle recorder), (recorder), )                           \
  X(OniStatus, oniRecorderDestroy, (OniRecorderHandle * recorder), (recorder), ONI_STATUS_ERROR)

namespace clutterseg::drivers::internal {
namespace {

struct OniApi {
#define CLUTTERSEG_ONI_POINTER(ret, name, params, args, fail) decltype(&::name) name{nullptr};
  CLUTTERSEG_ONI_FUNCTIONS(CLUTTERSEG_ONI_POINTER)
#undef CLUTTERSEG_ONI_POINTER
};

std::mutex g_load_mutex;
OniApi g_api;                                  // written once, under g_load_mutex
std::atomic<const OniApi*> g_loaded{nullptr};  // &g_api once every function is resolved
std::string g_library_path;
bool g_recordings_only = false;

// The directory of the running executable ("" when /proc is not there).
std::filesystem::path ExecutableDir() {
  std::error_code ec;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::filesystem::path() : exe.parent_path();
}

// True when `dir` holds the recordings-only layout.
bool IsRecordingsDir(const std::filesystem::path& dir) {
  std::error_code ec;
  return !dir.empty() && std::filesystem::exists(dir / CLUTTERSEG_OPENNI2_SONAME, ec) &&
         std::filesystem::exists(dir / "OpenNI2" / "Drivers" / "libOniFile.so.0", ec);
}

// Links to libOpenNI2 and libOniFile alone ("" when there are none): the installed ones
// beside the executable's prefix (bin/../lib/<multiarch>/clutterseg/openni2-recordings), or,
// for a binary of the build tree, the build tree's.
std::string RecordingsOnlyLibrary() {
#ifdef CLUTTERSEG_OPENNI2_RECORDINGS_DIR
  const std::filesystem::path exe_dir = ExecutableDir();
  if (exe_dir.empty()) return {};
  const std::filesystem::path installed =
      (exe_dir / CLUTTERSEG_OPENNI2_INSTALLED_RECORDINGS_DIR).lexically_normal();
  if (IsRecordingsDir(installed)) return (installed / CLUTTERSEG_OPENNI2_SONAME).string();
  const std::string build_tree = CLUTTERSEG_OPENNI2_BUILD_TREE;
  const std::filesystem::path built(CLUTTERSEG_OPENNI2_RECORDINGS_DIR);
  if (exe_dir.string().rfind(build_tree + "/", 0) == 0 && IsRecordingsDir(built)) {
    return (built / CLUTTERSEG_OPENNI2_SONAME).string();
  }
#endif
  return {};
}

}  // namespace

bool LoadOpenNI2Library(OpenNI2Drivers drivers, std::string* error) {
  std::lock_guard<std::mutex> lock(g_load_mutex);
  if (g_loaded.load(std::memory_order_acquire) != nullptr) return true;
  std::string path;
  if (drivers == OpenNI2Drivers::kRecordingsOnly) path = RecordingsOnlyLibrary();
  const bool recordings_only = !path.empty();
#ifdef CLUTTERSEG_OPENNI2_LIBRARY
  if (path.empty()) path = CLUTTERSEG_OPENNI2_LIBRARY;
#endif
  void* handle = path.empty() ? nullptr : dlopen(path.c_str(), RTLD_NOW | RTLD_GLOBAL);
  if (handle == nullptr) {
    // The build's path moved: the dynamic loader's search by soname.
    path = CLUTTERSEG_OPENNI2_SONAME;
    handle = dlopen(path.c_str(), RTLD_NOW | RTLD_GLOBAL);
  }
  if (handle == nullptr) {
    const char* why = dlerror();
    if (error != nullptr) {
      *error = "cannot load libOpenNI2 (" + path + "): " + (why != nullptr ? why : "unknown");
    }
    return false;
  }
  // Resolved from the handle, so these are libOpenNI2's own functions, never the forwarders
  // below. The handle is deliberately never closed: OpenNI2 stays loaded until exit.
#define CLUTTERSEG_ONI_RESOLVE(ret, name, params, args, fail)                            \
  g_api.name = reinterpret_cast<decltype(&::name)>(dlsym(handle, #name));                \
  if (g_api.name == nullptr) {                                                           \
    if (error != nullptr) *error = "libOpenNI2 (" + path + ") has no function " + #name; \
    return false;                                                                        \
  }
  CLUTTERSEG_ONI_FUNCTIONS(CLUTTERSEG_ONI_RESOLVE)
#undef CLUTTERSEG_ONI_RESOLVE
  // The path OpenNI2 derives its driver directory from (an already loaded copy of the same
  // file keeps its first path).
  Dl_info info{};
  g_library_path =
      dladdr(reinterpret_cast<void*>(g_api.oniInitialize), &info) != 0 && info.dli_fname != nullptr
          ? std::string(info.dli_fname)
          : path;
  g_recordings_only = recordings_only && g_library_path == path;
  g_loaded.store(&g_api, std::memory_order_release);
  return true;
}

std::string LoadedOpenNI2Library() {
  std::lock_guard<std::mutex> lock(g_load_mutex);
  return g_library_path;
}

bool OpenNI2LoadedForRecordingsOnly() {
  std::lock_guard<std::mutex> lock(g_load_mutex);
  return g_recordings_only;
}

namespace {

const OniApi* Api() {
  const OniApi* api = g_loaded.load(std::memory_order_acquire);
  if (api != nullptr) return api;
  if (!LoadOpenNI2Library(OpenNI2Drivers::kAll, nullptr)) return nullptr;
  return g_loaded.load(std::memory_order_acquire);
}

}  // namespace
}  // namespace clutterseg::drivers::internal

// The forwarders (declared by OniCAPI.h with C linkage and default visibility).
#define CLUTTERSEG_ONI_FORWARD(ret, name, params, args, fail)                                \
  ret name params {                                                                          \
    const clutterseg::drivers::internal::OniApi* api = clutterseg::drivers::internal::Api(); \
    if (api == nullptr) return fail;                                                         \
    return api->name args;                                                                   \
  }
CLUTTERSEG_ONI_FUNCTIONS(CLUTTERSEG_ONI_FORWARD)
#undef CLUTTERSEG_ONI_FORWARD
