# Cross toolchain for 64-bit ARM Linux (Raspberry Pi 3/4/5 with a 64-bit OS, Jetson, i.MX8, RK3399...)
# with Debian's cross compiler (g++-aarch64-linux-gnu) and multiarch target libraries
# (dpkg --add-architecture arm64; apt-get install libturbojpeg0-dev:arm64 libpng-dev:arm64).
# tools/cross.sh does all of that. A sysroot instead of multiarch: -DEPITRACK_SYSROOT=/path.
# CPU tuning is separate: -DEPITRACK_CPU_FLAGS_FILE=toolchains/cpu/cortex-a72.cmake (optional).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(EPITRACK_TARGET_TRIPLE aarch64-linux-gnu)
include(${CMAKE_CURRENT_LIST_DIR}/linux-cross-common.cmake)
