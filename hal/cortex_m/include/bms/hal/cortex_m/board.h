/* Board support for QEMU's MPS2 boards (mps2-an500 Cortex-M7, mps2-an386 Cortex-M4F):
 * the C-level functions of startup_mps2.c, semihosting.c and stdio_semihost.c.
 * C++ code uses the classes in bms/hal/cortex_m/board.hpp. */
#ifndef BMS_HAL_CORTEX_M_BOARD_H
#define BMS_HAL_CORTEX_M_BOARD_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Semihosting (ARM "Angel" interface, bkpt 0xAB); QEMU needs -semihosting. */
void bms_semihost_write0(const char* text);           /* SYS_WRITE0: NUL-terminated text to the console */
void bms_semihost_write(const char* text, size_t len); /* SYS_WRITE on the console (":tt") */
__attribute__((noreturn)) void bms_semihost_exit(int status); /* SYS_EXIT_EXTENDED: QEMU exits with `status` */

/* Stack region of the linker script, and how much of it was ever used (painted at reset). */
size_t bms_board_stack_size_bytes(void);
size_t bms_board_stack_used_bytes(void);

/* Called by Reset_Handler after the constructors, and with main()'s return value. Weak
 * defaults do nothing / exit through semihosting; bms_board_stdio (stdio_semihost.c) opens
 * newlib's stdio on the semihosting console and exits through exit() (stdio flushed). */
void bms_board_stdio_init(void);
__attribute__((noreturn)) void bms_board_exit(int status);

/* Heap handed out by _sbrk to newlib (bms_board_stdio only; 0 otherwise). */
size_t bms_board_heap_used_bytes(void);

#ifdef __cplusplus
}
#endif

#endif /* BMS_HAL_CORTEX_M_BOARD_H */
