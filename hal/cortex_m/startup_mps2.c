/* Startup for QEMU's MPS2 boards (mps2-an500 Cortex-M7, mps2-an386 Cortex-M4F).
 *
 * Reset_Handler: enables the FPU (CPACR CP10/CP11 full access) before any floating-point
 * instruction can run, copies .data from flash, zeroes .bss, paints the unused stack (for the
 * high-water mark, bms_board_stack_used_bytes), runs the C/C++ constructors
 * (__libc_init_array), calls main() and passes its return value to bms_board_exit(): with
 * semihosting that becomes QEMU's exit status.
 * Faults print one line through semihosting and exit with status 3, so a broken image ends a
 * test instead of hanging it.
 * Written in C because C++ may not call main(). */
#include <stddef.h>
#include <stdint.h>

#include "bms/hal/cortex_m/board.h"

extern uint32_t __data_load__, __data_start__, __data_end__;
extern uint32_t __bss_start__, __bss_end__;
extern uint32_t __StackLimit, __StackTop;

int main(void);
void __libc_init_array(void);

void Reset_Handler(void);
void bms_reset_continue(void);
void bms_default_handler(void);
void NMI_Handler(void) __attribute__((weak, alias("bms_default_handler")));
void HardFault_Handler(void) __attribute__((weak, alias("bms_default_handler")));
void MemManage_Handler(void) __attribute__((weak, alias("bms_default_handler")));
void BusFault_Handler(void) __attribute__((weak, alias("bms_default_handler")));
void UsageFault_Handler(void) __attribute__((weak, alias("bms_default_handler")));
void SVC_Handler(void) __attribute__((weak, alias("bms_default_handler")));
void DebugMon_Handler(void) __attribute__((weak, alias("bms_default_handler")));
void PendSV_Handler(void) __attribute__((weak, alias("bms_default_handler")));
void SysTick_Handler(void) __attribute__((weak, alias("bms_default_handler")));

typedef void (*bms_vector_t)(void);

/* The initial stack pointer, declared as a function so that it is an address constant of the
 * vector table's element type. */
extern void bms_initial_sp(void) __asm("__StackTop");

/* Initial stack pointer, 15 system exceptions, then the board's interrupts (unused here:
 * all go to the default handler). */
#define BMS_EXTERNAL_IRQS 32
#define BMS_IRQ2 bms_default_handler, bms_default_handler
#define BMS_IRQ8 BMS_IRQ2, BMS_IRQ2, BMS_IRQ2, BMS_IRQ2
__attribute__((section(".isr_vector"), used)) const bms_vector_t bms_vector_table[16 + BMS_EXTERNAL_IRQS] = {
    bms_initial_sp,
    Reset_Handler,
    NMI_Handler,
    HardFault_Handler,
    MemManage_Handler,
    BusFault_Handler,
    UsageFault_Handler,
    0, 0, 0, 0,
    SVC_Handler,
    DebugMon_Handler,
    0,
    PendSV_Handler,
    SysTick_Handler,
    BMS_IRQ8, BMS_IRQ8, BMS_IRQ8, BMS_IRQ8,
};

/* Naked: no compiler-generated code (which might touch FP registers) before the FPU is on. */
__attribute__((naked, noreturn)) void Reset_Handler(void) {
  __asm volatile(
      "ldr r0, =0xE000ED88\n" /* SCB->CPACR */
      "ldr r1, [r0]\n"
      "orr r1, r1, #(0xF << 20)\n" /* CP10, CP11: full access */
      "str r1, [r0]\n"
      "dsb\n"
      "isb\n"
      "b bms_reset_continue\n");
}

#define BMS_STACK_PAINT 0xC5AC5AC5u

/* Weak defaults; bms_board_stdio (stdio_semihost.c) replaces both for programs using stdio. */
__attribute__((weak)) void bms_board_stdio_init(void) {}
__attribute__((weak, noreturn)) void bms_board_exit(int status) { bms_semihost_exit(status); }
__attribute__((weak)) size_t bms_board_heap_used_bytes(void) { return 0u; }

__attribute__((noreturn, used)) void bms_reset_continue(void) {
  const uint32_t* src = &__data_load__;
  for (uint32_t* dst = &__data_start__; dst < &__data_end__;) {
    *dst++ = *src++;
  }
  for (uint32_t* dst = &__bss_start__; dst < &__bss_end__;) {
    *dst++ = 0u;
  }
  /* Paint the stack below the current frame (leave 64 bytes of margin). */
  uint32_t* sp;
  __asm volatile("mov %0, sp" : "=r"(sp));
  for (volatile uint32_t* p = &__StackLimit; p < sp - 16;) {
    *p++ = BMS_STACK_PAINT;
  }
  __libc_init_array();
  bms_board_stdio_init();
  bms_board_exit(main());
}

size_t bms_board_stack_size_bytes(void) {
  return (size_t)((uintptr_t)&__StackTop - (uintptr_t)&__StackLimit);
}

size_t bms_board_stack_used_bytes(void) {
  const uint32_t* p = &__StackLimit;
  while (p < &__StackTop && *p == BMS_STACK_PAINT) {
    ++p;
  }
  return (size_t)((uintptr_t)&__StackTop - (uintptr_t)p);
}

/* With -nostartfiles there are no crti/crtn: __libc_init_array calls _init, exit calls _fini. */
void _init(void) {}
void _fini(void) {}
void* __dso_handle = 0;

static void put_hex(char* out, uint32_t v) {
  for (int i = 7; i >= 0; --i) {
    const uint32_t d = v & 0xFu;
    out[i] = (char)(d < 10u ? '0' + (int)d : 'A' + (int)(d - 10u));
    v >>= 4u;
  }
}

/* Any unexpected exception: report the exception number and the CFSR, exit with status 3. */
void bms_default_handler(void) {
  uint32_t ipsr;
  __asm volatile("mrs %0, ipsr" : "=r"(ipsr));
  const uint32_t cfsr = *(volatile const uint32_t*)0xE000ED28u;
  char line[] = "board: unexpected exception 0x........ CFSR 0x........\n";
  put_hex(line + 30, ipsr);
  put_hex(line + 45, cfsr);
  bms_semihost_write0(line);
  bms_semihost_exit(3);
}
