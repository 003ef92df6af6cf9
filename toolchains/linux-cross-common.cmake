# Shared part of the Debian cross toolchains: compilers by triple, multiarch library directory,
# the find-root-path trio, an optional sysroot from the cache, and qemu-user as the emulator so
# ctest (and catch_discover_tests) can run target binaries on the build machine.
set(EPITRACK_SYSROOT "" CACHE PATH "Target sysroot (empty: Debian multiarch on the build machine)")
set(CMAKE_C_COMPILER ${EPITRACK_TARGET_TRIPLE}-gcc)
set(CMAKE_CXX_COMPILER ${EPITRACK_TARGET_TRIPLE}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${EPITRACK_TARGET_TRIPLE})
if(EPITRACK_SYSROOT)
  set(CMAKE_SYSROOT ${EPITRACK_SYSROOT})
  set(CMAKE_FIND_ROOT_PATH ${EPITRACK_SYSROOT})
  set(_qemu_ld_prefix ${EPITRACK_SYSROOT})
else()
  # Multiarch: target headers and libraries live in the build machine's /usr (lib/<triple>).
  set(CMAKE_FIND_ROOT_PATH /usr/${EPITRACK_TARGET_TRIPLE} /)
  set(_qemu_ld_prefix /usr/${EPITRACK_TARGET_TRIPLE})
endif()
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
if(CMAKE_SYSTEM_PROCESSOR STREQUAL "aarch64")
  set(_qemu qemu-aarch64)
else()
  set(_qemu qemu-arm)
endif()
find_program(EPITRACK_QEMU ${_qemu})
if(EPITRACK_QEMU AND EPITRACK_SYSROOT)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${EPITRACK_QEMU} -L ${_qemu_ld_prefix})
elseif(EPITRACK_QEMU)
  # Debian's cross loader (/usr/<triple>/lib, libc6-<arch>-cross) must run with the C library of
  # the same build. Under -L, the loader's default path /lib/<triple> falls through to the build
  # machine's multiarch libc6:<arch> (installed with libturbojpeg0-dev:<arch>), usually another
  # Debian revision: with that pair, pthread_create spins forever (any program starting a thread
  # hung under emulation). LD_LIBRARY_PATH puts the loader's own libc first; the multiarch
  # directory still provides libjpeg-turbo and libpng.
  set(CMAKE_CROSSCOMPILING_EMULATOR
      ${EPITRACK_QEMU} -L ${_qemu_ld_prefix} -E
      LD_LIBRARY_PATH=${_qemu_ld_prefix}/lib:/usr/lib/${EPITRACK_TARGET_TRIPLE})
endif()
# For scripts that run target programs themselves (.ci/cross_aarch64.sh reads it from the cache).
set(EPITRACK_TARGET_EMULATOR "${CMAKE_CROSSCOMPILING_EMULATOR}" CACHE INTERNAL
    "Command prefix that runs a target program on the build machine")
if(EPITRACK_CPU_FLAGS_FILE)
  include(${EPITRACK_CPU_FLAGS_FILE})
endif()
