#pragma once
/// \file The process-wide Embree device and its error hook (internal to accel/).
///
/// The error callback never throws (it runs inside Embree): it records the first error,
/// and `check()` turns a recorded error into a cmlt::SceneError after each API call.
#include <embree3/rtcore.h>

#include <memory>
#include <mutex>
#include <string>

namespace cmlt {

class EmbreeDevice {
public:
    /// Shared device; created on first use, released when the last user goes.
    static std::shared_ptr<EmbreeDevice> get();
    ~EmbreeDevice();

    RTCDevice handle() const { return m_device; }
    /// Throw SceneError("<what>: Embree error ...") if an error was recorded; clears it.
    void check(const char* what);

private:
    EmbreeDevice();
    static void error_callback(void* user, RTCError code, const char* str);

    RTCDevice m_device = nullptr;
    std::mutex m_mutex;
    std::string m_error;
};

const char* embree_error_name(RTCError code);

}  // namespace cmlt
