#include "accel/embree_device.h"

#include "util/error.h"

namespace cmlt {

const char* embree_error_name(RTCError code) {
    switch (code) {
        case RTC_ERROR_NONE: return "RTC_ERROR_NONE";
        case RTC_ERROR_UNKNOWN: return "RTC_ERROR_UNKNOWN";
        case RTC_ERROR_INVALID_ARGUMENT: return "RTC_ERROR_INVALID_ARGUMENT";
        case RTC_ERROR_INVALID_OPERATION: return "RTC_ERROR_INVALID_OPERATION";
        case RTC_ERROR_OUT_OF_MEMORY: return "RTC_ERROR_OUT_OF_MEMORY";
        case RTC_ERROR_UNSUPPORTED_CPU: return "RTC_ERROR_UNSUPPORTED_CPU";
        case RTC_ERROR_CANCELLED: return "RTC_ERROR_CANCELLED";
    }
    return "RTC_ERROR_?";
}

std::shared_ptr<EmbreeDevice> EmbreeDevice::get() {
    static std::mutex mutex;
    static std::weak_ptr<EmbreeDevice> cached;
    std::lock_guard<std::mutex> lock(mutex);
    std::shared_ptr<EmbreeDevice> dev = cached.lock();
    if (!dev) {
        dev.reset(new EmbreeDevice());
        cached = dev;
    }
    return dev;
}

EmbreeDevice::EmbreeDevice() {
    m_device = rtcNewDevice(nullptr);
    if (!m_device) {
        RTCError code = rtcGetDeviceError(nullptr);
        CMLT_THROW(SceneError, "cannot create the Embree device: " << embree_error_name(code));
    }
    rtcSetDeviceErrorFunction(m_device, &EmbreeDevice::error_callback, this);
    rtcSetDeviceMemoryMonitorFunction(m_device, &EmbreeDevice::memory_callback, this);
}

EmbreeDevice::~EmbreeDevice() {
    if (m_device) rtcReleaseDevice(m_device);
}

void EmbreeDevice::error_callback(void* user, RTCError code, const char* str) {
    auto* self = static_cast<EmbreeDevice*>(user);
    std::lock_guard<std::mutex> lock(self->m_mutex);
    if (self->m_error.empty()) {
        self->m_error = std::string(embree_error_name(code)) + ": " + (str ? str : "");
    }
}

bool EmbreeDevice::memory_callback(void* user, ssize_t bytes, bool /*post*/) {
    // Called for every allocation (bytes > 0) and release (bytes < 0); never refuses.
    static_cast<EmbreeDevice*>(user)->m_bytes.fetch_add(int64_t(bytes), std::memory_order_relaxed);
    return true;
}

void EmbreeDevice::check(const char* what) {
    std::string err;
    {
        std::lock_guard<std::mutex> lock(m_mutex);
        err.swap(m_error);
    }
    if (!err.empty()) CMLT_THROW(SceneError, what << ": Embree error " << err);
}

}  // namespace cmlt
