# CPU tuning for a Raspberry Pi 4 (Cortex-A72). Optional; the default cross build is generic ARMv8.
string(APPEND CMAKE_CXX_FLAGS_INIT " -mcpu=cortex-a72")
