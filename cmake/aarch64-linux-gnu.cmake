# Cross-compiling for aarch64 (64-bit Arm Linux: Raspberry Pi 4/5, Jetson) with Debian's cross
# toolchain (g++-aarch64-linux-gnu) against a private sysroot of arm64 packages
# (OCCMAP_AARCH64_SYSROOT, made by scripts/check-aarch64.sh: the .debs unpacked, not installed,
# so nothing of the amd64 system is replaced). Tests run under qemu-aarch64 with the sysroot.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)

if(NOT OCCMAP_AARCH64_SYSROOT)
  set(OCCMAP_AARCH64_SYSROOT "$ENV{OCCMAP_AARCH64_SYSROOT}")
endif()
if(NOT IS_DIRECTORY "${OCCMAP_AARCH64_SYSROOT}")
  message(FATAL_ERROR "OCCMAP_AARCH64_SYSROOT: expected the arm64 sysroot made by scripts/check-aarch64.sh, found '${OCCMAP_AARCH64_SYSROOT}'")
endif()
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES OCCMAP_AARCH64_SYSROOT)
set(sysroot "${OCCMAP_AARCH64_SYSROOT}")
# The cross compiler brings its own libc and libstdc++ (/usr/aarch64-linux-gnu); the libraries
# come from the sysroot, headers that are the same on every architecture from the host.
set(CMAKE_FIND_ROOT_PATH "${sysroot}" /usr/aarch64-linux-gnu)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE BOTH)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
# (A few arm64 packages, libarmadillo11 and libogdi4.1 among them, put their libraries in /usr/lib;
# libpulse, which FFmpeg's libavdevice needs, finds libpulsecommon by its RUNPATH, which a cross
# linker does not follow.)
set(libdirs "${sysroot}/usr/lib/aarch64-linux-gnu" "${sysroot}/lib/aarch64-linux-gnu" "${sysroot}/usr/lib"
  "${sysroot}/usr/lib/aarch64-linux-gnu/pulseaudio")
string(REPLACE ";" ",-rpath-link," rpath_link "${libdirs}")
string(REPLACE ";" ":" ld_library_path "${libdirs}")
set(CMAKE_EXE_LINKER_FLAGS_INIT "-Wl,-rpath-link,${rpath_link}")
set(CMAKE_SHARED_LINKER_FLAGS_INIT "-Wl,-rpath-link,${rpath_link}")
# Debian's libopencv-dev (its CMake package) cannot be co-installed for two architectures and
# lists every module; this one names the modules the build asks for in the sysroot.
set(OpenCV_DIR "${CMAKE_CURRENT_LIST_DIR}/aarch64")
# pkg-config (FFmpeg, libmosquitto, cpp-httplib) reads the sysroot's .pc files only, and puts
# the sysroot in front of the paths they name.
set(ENV{PKG_CONFIG_LIBDIR} "${sysroot}/usr/lib/aarch64-linux-gnu/pkgconfig:${sysroot}/usr/share/pkgconfig")
set(ENV{PKG_CONFIG_SYSROOT_DIR} "${sysroot}")
unset(ENV{PKG_CONFIG_PATH})
set(CMAKE_CROSSCOMPILING_EMULATOR qemu-aarch64 -L "${sysroot}" -E "LD_LIBRARY_PATH=${ld_library_path}")
