# Cortex-M4F with the single-precision FPU (fpv4-sp-d16, hard float ABI): f32 in hardware,
# f64 in software (libgcc). Runs on QEMU's mps2-an386 board (hal/cortex_m). Used by the
# `cortex-m4f` preset, which builds the firmware with Scalar = float.
set(BMS_CPU_FLAGS "-mcpu=cortex-m4 -mfpu=fpv4-sp-d16 -mfloat-abi=hard -mthumb")
set(BMS_CORTEX_M_CPU cortex-m4f)
set(BMS_QEMU_MACHINE mps2-an386)
include(${CMAKE_CURRENT_LIST_DIR}/arm-none-eabi-common.cmake)
