/* newlib stdio on the semihosting console, for test programs that print with printf
 * (the target replay application). Linked as an object library (bms_board_stdio) so that
 * its strong definitions replace the weak defaults of startup_mps2.c.
 *
 * newlib's stdio allocates (the stdout buffer; the bignums of printf's %g conversion), so
 * this also provides _sbrk over the linker script's heap region. The firmware itself never
 * allocates: target/tools/noheap_check.py checks that only libc's objects reference malloc. */
#include <errno.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include "bms/hal/cortex_m/board.h"

void initialise_monitor_handles(void);
void* _sbrk(ptrdiff_t increment);

extern char __heap_start__[];
extern char __heap_end__[];

static char* heap_top = __heap_start__;

void bms_board_stdio_init(void) { initialise_monitor_handles(); }

void bms_board_exit(int status) { exit(status); } /* flushes stdio; rdimon's _exit passes status to QEMU */

void* _sbrk(ptrdiff_t increment) {
  if (increment < 0 || increment > __heap_end__ - heap_top) {
    errno = ENOMEM;
    return (void*)-1;
  }
  char* previous = heap_top;
  heap_top += increment;
  return previous;
}

size_t bms_board_heap_used_bytes(void) { return (size_t)(heap_top - __heap_start__); }
