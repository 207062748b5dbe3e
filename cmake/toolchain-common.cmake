# The part of cmake/toolchain-<arch>.cmake that is the same for every Debian cross target; the file
# that includes this one sets SSIU_CROSS_TRIPLET and CMAKE_SYSTEM_PROCESSOR.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_C_COMPILER ${SSIU_CROSS_TRIPLET}-gcc)
set(CMAKE_CXX_COMPILER ${SSIU_CROSS_TRIPLET}-g++)
set(CMAKE_LIBRARY_ARCHITECTURE ${SSIU_CROSS_TRIPLET})

# The cross toolchain's own libc/libstdc++ live in /usr/<triplet>; the multiarch -dev packages in
# /usr/include and /usr/lib/<triplet>, found under the root "/" through CMAKE_LIBRARY_ARCHITECTURE.
# Programs (python3, qemu) come from the host; libraries and packages only from the target's paths.
set(CMAKE_FIND_ROOT_PATH /usr/${SSIU_CROSS_TRIPLET} /)
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# pkg-config answers for the target: only its .pc files (and the architecture-independent ones).
set(ENV{PKG_CONFIG_LIBDIR} /usr/lib/${SSIU_CROSS_TRIPLET}/pkgconfig:/usr/share/pkgconfig)
set(ENV{PKG_CONFIG_PATH} "")

# SSIU_CROSS_SYSROOT: the target's packages unpacked into a directory rather than installed beside the
# host's (scripts/cross-test.sh does so when their versions differ from the host's). Searched first;
# pkg-config's paths are prefixed with it; the linker follows the libraries' own dependencies there.
set(CMAKE_TRY_COMPILE_PLATFORM_VARIABLES SSIU_CROSS_SYSROOT)
if(SSIU_CROSS_SYSROOT)
  list(PREPEND CMAKE_FIND_ROOT_PATH ${SSIU_CROSS_SYSROOT})
  set(ENV{PKG_CONFIG_LIBDIR} ${SSIU_CROSS_SYSROOT}/usr/lib/${SSIU_CROSS_TRIPLET}/pkgconfig:${SSIU_CROSS_SYSROOT}/usr/share/pkgconfig)
  set(ENV{PKG_CONFIG_SYSROOT_DIR} ${SSIU_CROSS_SYSROOT})
  set(_ssiu_libdirs ${SSIU_CROSS_SYSROOT}/lib/${SSIU_CROSS_TRIPLET}:${SSIU_CROSS_SYSROOT}/usr/lib/${SSIU_CROSS_TRIPLET})
  set(CMAKE_EXE_LINKER_FLAGS_INIT "-Wl,-rpath-link,${_ssiu_libdirs}")
  set(CMAKE_SHARED_LINKER_FLAGS_INIT "-Wl,-rpath-link,${_ssiu_libdirs}")
endif()

# Test programs (gtest_discover_tests and ctest) run under qemu-user with the target's multiarch runtime
# (libc6:<arch>, libstdc++6:<arch> in /lib/<triplet>, found by qemu at their host paths). Not with
# -L /usr/<triplet>: that loader (libc6-<arch>-cross, 2.36-8cross1 in Debian 12) would load the multiarch
# libc.so.6 of another glibc build (2.36-9+deb12u*) through /etc/ld.so.cache, and then a program hangs in
# its first pthread_create.
# With a sysroot, qemu takes it as the programs' root (-L): their loader and every library come from it.
find_program(SSIU_CROSS_QEMU NAMES qemu-${SSIU_CROSS_QEMU_ARCH} qemu-${SSIU_CROSS_QEMU_ARCH}-static REQUIRED)
if(SSIU_CROSS_SYSROOT)
  set(CMAKE_CROSSCOMPILING_EMULATOR ${SSIU_CROSS_QEMU} -L ${SSIU_CROSS_SYSROOT})
else()
  set(CMAKE_CROSSCOMPILING_EMULATOR ${SSIU_CROSS_QEMU})
endif()

# GCC's -Wpsabi notes on ARM ("parameter passing for argument of type ... changed in GCC 9.1"/"10.1")
# concern calls between objects built by different GCC versions, which a build from source never makes.
# SSIU_CROSS_EXTRA_FLAGS: what the file that includes this one adds for its target.
string(JOIN " " _ssiu_flags -Wno-psabi ${SSIU_CROSS_EXTRA_FLAGS})
set(CMAKE_C_FLAGS_INIT "${_ssiu_flags}")
set(CMAKE_CXX_FLAGS_INIT "${_ssiu_flags}")
