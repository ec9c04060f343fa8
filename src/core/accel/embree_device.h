#pragma once
/// \file The process-wide Embree device and its error hook (internal to accel/).
///
/// The error callback never throws (it runs inside Embree): it records the first error,
/// and `check()` turns a recorded error into a cmlt::SceneError after each API call.
#include <embree3/rtcore.h>

#include <atomic>
#include <cstdint>
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
    /// Bytes Embree holds for this device now (its memory monitor callback: BVH nodes,
    /// leaves, build scratch not yet freed; buffers shared with the caller are not
    /// counted). Accel takes differences around its commits to size each BVH.
    int64_t allocated_bytes() const { return m_bytes.load(std::memory_order_relaxed); }

private:
    EmbreeDevice();
    static void error_callback(void* user, RTCError code, const char* str);
    static bool memory_callback(void* user, ssize_t bytes, bool post);

    RTCDevice m_device = nullptr;
    std::mutex m_mutex;
    std::string m_error;
    std::atomic<int64_t> m_bytes{0};
};

const char* embree_error_name(RTCError code);

}  // namespace cmlt
