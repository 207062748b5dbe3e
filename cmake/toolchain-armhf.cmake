# Cross build for 32-bit ARM, hard float (Cortex-A7/A9 class; Debian armhf: ARMv7-A, VFPv3-D16, Thumb-2)
# with Debian's cross compiler and multiarch packages: scripts/cross-test.sh armhf (see
# docs/flight.md, "ARM"). Tests run under qemu-user.
set(SSIU_CROSS_TRIPLET arm-linux-gnueabihf)
set(CMAKE_SYSTEM_PROCESSOR armv7l)
set(SSIU_CROSS_QEMU_ARCH arm)
# GCC 12 for 32-bit ARM reports -Wmaybe-uninitialized inside Eigen's fixed-maximum-size products
# (Matrix<double, Dynamic, 1, 0, 6, 1>): a false positive, as in the sanitizer builds (CMakeLists.txt).
set(SSIU_CROSS_EXTRA_FLAGS -Wno-maybe-uninitialized)
include(${CMAKE_CURRENT_LIST_DIR}/toolchain-common.cmake)
