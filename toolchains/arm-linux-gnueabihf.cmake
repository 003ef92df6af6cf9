# Cross toolchain for 32-bit ARM Linux with hardware float (Raspberry Pi OS 32-bit, BeagleBone,
# i.MX6...) with Debian's g++-arm-linux-gnueabihf and armhf multiarch libraries. See
# aarch64-linux-gnu.cmake for the options. Debian's armhf baseline is ARMv7-A with VFPv3-D16 and no
# NEON: the LK kernels choose NEON at run time (algo/flow/lk_kernels_neon32.cpp), and the project
# adds large-file and 64-bit time support for 32-bit targets (cmake/EpitrackCompileOptions.cmake).
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR arm)
set(EPITRACK_TARGET_TRIPLE arm-linux-gnueabihf)
include(${CMAKE_CURRENT_LIST_DIR}/linux-cross-common.cmake)
