# Cross build for 64-bit ARM (Cortex-A53 class) with Debian's cross compiler and multiarch packages:
# scripts/cross-test.sh aarch64 (see docs/flight.md, "ARM"). Tests run under qemu-user.
set(SSIU_CROSS_TRIPLET aarch64-linux-gnu)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(SSIU_CROSS_QEMU_ARCH aarch64)
include(${CMAKE_CURRENT_LIST_DIR}/toolchain-common.cmake)
