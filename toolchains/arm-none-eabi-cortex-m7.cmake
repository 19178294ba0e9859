# Cortex-M7 with the double-precision FPU (fpv5-d16, hard float ABI): f64 arithmetic in
# hardware. Runs on QEMU's mps2-an500 board (hal/cortex_m). Used by the `cortex-m7` preset.
set(BMS_CPU_FLAGS "-mcpu=cortex-m7 -mfpu=fpv5-d16 -mfloat-abi=hard -mthumb")
set(BMS_CORTEX_M_CPU cortex-m7)
set(BMS_QEMU_MACHINE mps2-an500)
include(${CMAKE_CURRENT_LIST_DIR}/arm-none-eabi-common.cmake)
