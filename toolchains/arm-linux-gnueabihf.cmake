# Cross toolchain for 32-bit ARM Linux with hardware float (Raspberry Pi OS 32-bit, BeagleBone,
# i.MX6...) with Debian's g++-arm-linux-gnueabihf and armhf multiarch libraries. See
# aarch64-linux-gnu.cmake for the options.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(EPITRACK_TARGET_TRIPLE arm-linux-gnueabihf)
include(${CMAKE_CURRENT_LIST_DIR}/linux-cross-common.cmake)
