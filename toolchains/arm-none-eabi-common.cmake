# Shared part of the arm-none-eabi toolchain files (included by arm-none-eabi-cortex-*.cmake,
# which set BMS_CPU_FLAGS and BMS_QEMU_MACHINE first). Bare metal, newlib-nano, semihosting;
# the board's startup code and linker script come from hal/cortex_m (no crt0 of the toolchain).
set(CMAKE_SYSTEM_NAME Generic)
set(CMAKE_SYSTEM_PROCESSOR arm)

set(CMAKE_C_COMPILER arm-none-eabi-gcc)
set(CMAKE_CXX_COMPILER arm-none-eabi-g++)
set(CMAKE_ASM_COMPILER arm-none-eabi-gcc)
# try_compile cannot link without the board's startup code and linker script.
set(CMAKE_TRY_COMPILE_TARGET_TYPE STATIC_LIBRARY)

find_program(BMS_ARM_OBJCOPY arm-none-eabi-objcopy)
find_program(BMS_ARM_NM arm-none-eabi-nm)
find_program(BMS_ARM_SIZE arm-none-eabi-size)
find_program(BMS_ARM_READELF arm-none-eabi-readelf)
find_program(BMS_ARM_OBJDUMP arm-none-eabi-objdump)
find_program(BMS_QEMU_SYSTEM_ARM qemu-system-arm)

# Code generation for every C/C++ file of the cross build:
#   -ffunction-sections -fdata-sections  with --gc-sections: unused functions and data are dropped
#   -fstack-usage -fcallgraph-info=su    .su and .ci files next to each object, for the
#                                        worst-case stack along the call graph (target/tools)
#   -fno-exceptions -fno-rtti            C++ without unwinding tables, typeinfo or throw
#   -fno-threadsafe-statics              no __cxa_guard_* (single-threaded, no RTOS)
#   -ffp-contract=off                    no fused multiply-add: GCC fuses a*b+c by default in
#                                        C++ where the FPU has VFMA (M7: f64, M4F: f32); the host
#                                        (x86-64) does not, and unfused the Cortex-M7 replay
#                                        equals the host's bit for bit (docs/results/target.md)
#                                        (-DBMS_FP_CONTRACT=fast restores GCC's default)
if(NOT DEFINED BMS_FP_CONTRACT)
  set(BMS_FP_CONTRACT off)
endif()
set(_bms_common "${BMS_CPU_FLAGS} -ffunction-sections -fdata-sections -fstack-usage -fcallgraph-info=su -ffp-contract=${BMS_FP_CONTRACT}")
set(CMAKE_C_FLAGS_INIT "${_bms_common}")
set(CMAKE_CXX_FLAGS_INIT "${_bms_common} -fno-exceptions -fno-rtti -fno-threadsafe-statics")
set(CMAKE_ASM_FLAGS_INIT "${BMS_CPU_FLAGS}")
# newlib-nano; the board library adds -nostartfiles, its linker script and semihosting (rdimon).
set(CMAKE_EXE_LINKER_FLAGS_INIT "${BMS_CPU_FLAGS} -Wl,--gc-sections --specs=nano.specs")

# Programs from the build machine; libraries and headers only from the cross sysroot, except
# CMake packages: Eigen is header-only and its host package works as it is.
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE NEVER)

set(CMAKE_EXECUTABLE_SUFFIX_C .elf)
set(CMAKE_EXECUTABLE_SUFFIX_CXX .elf)
