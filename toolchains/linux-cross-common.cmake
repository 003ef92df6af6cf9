# Shared part of the Debian cross toolchains: compilers by triple, multiarch library directory,
# the find-root-path trio, an optional sysroot from the cache, and qemu-user as the emulator so
# ctest (and catch_discover_tests) can run target binaries on the build machine.
set(EPITRACK_SYSROOT "" CACHE PATH "Target sysroot (empty: Debian multiarch on the build machine)")
set(EPITRACK_TARGET_LIBS "" CACHE PATH
    "Target libjpeg-turbo, libpng and zlib unpacked from Debian packages (tools/cross_libs.sh)")
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
set(_target_lib_path /usr/lib/${EPITRACK_TARGET_TRIPLE})
if(EPITRACK_TARGET_LIBS)
  # Libraries unpacked beside the cross compiler's own C library instead of installed through
  # multiarch (whose versions must match the build machine's, tools/cross_libs.sh says why):
  # searched first, found by the linker for the libraries' own dependencies (libpng -> zlib) and
  # by the emulator's loader at run time.
  list(PREPEND CMAKE_FIND_ROOT_PATH ${EPITRACK_TARGET_LIBS})
  set(_target_lib_path
      ${EPITRACK_TARGET_LIBS}/usr/lib/${EPITRACK_TARGET_TRIPLE}:${EPITRACK_TARGET_LIBS}/lib/${EPITRACK_TARGET_TRIPLE})
  string(REPLACE ":" ",-rpath-link," _rpath_link "${_target_lib_path}")
  # set, not appended: CMake reads the toolchain file more than once.
  set(CMAKE_EXE_LINKER_FLAGS_INIT "-Wl,-rpath-link,${_rpath_link}")
  set(CMAKE_SHARED_LINKER_FLAGS_INIT "-Wl,-rpath-link,${_rpath_link}")
endif()
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES EPITRACK_SYSROOT EPITRACK_TARGET_LIBS)
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
  # directory (or EPITRACK_TARGET_LIBS) still provides libjpeg-turbo and libpng.
  set(CMAKE_CROSSCOMPILING_EMULATOR
      ${EPITRACK_QEMU} -L ${_qemu_ld_prefix} -E
      LD_LIBRARY_PATH=${_qemu_ld_prefix}/lib:${_target_lib_path})
endif()
# For scripts that run target programs themselves (.ci/cross_aarch64.sh reads it from the cache).
set(EPITRACK_TARGET_EMULATOR "${CMAKE_CROSSCOMPILING_EMULATOR}" CACHE INTERNAL
    "Command prefix that runs a target program on the build machine")
if(EPITRACK_CPU_FLAGS_FILE)
  include(${EPITRACK_CPU_FLAGS_FILE})
endif()
