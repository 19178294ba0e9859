/* Semihosting calls (ARM semihosting v2, "bkpt 0xAB" on M-profile). QEMU implements them
 * with -semihosting; on real hardware they need a debugger attached. */
#include <stdint.h>

#include "bms/hal/cortex_m/board.h"

enum {
  kSysOpen = 0x01,
  kSysWrite = 0x05,
  kSysWrite0 = 0x04,
  kSysExitExtended = 0x20,
  kAdpStoppedApplicationExit = 0x20026,
};

static uint32_t semihost_call(uint32_t op, const void* arg) {
  uint32_t result;
  __asm volatile(
      "mov r0, %1\n"
      "mov r1, %2\n"
      "bkpt 0xAB\n"
      "mov %0, r0\n"
      : "=r"(result)
      : "r"(op), "r"(arg)
      : "r0", "r1", "memory");
  return result;
}

void bms_semihost_write0(const char* text) { (void)semihost_call(kSysWrite0, text); }

/* The console handle: ":tt" opened for writing (mode 4 = "w"). Opened on first use. */
static uint32_t console_handle(void) {
  static uint32_t handle = 0xFFFFFFFFu;
  if (handle == 0xFFFFFFFFu) {
    const uint32_t args[3] = {(uint32_t)(uintptr_t) ":tt", 4u, 3u};
    handle = semihost_call(kSysOpen, args);
  }
  return handle;
}

void bms_semihost_write(const char* text, size_t len) {
  const uint32_t args[3] = {console_handle(), (uint32_t)(uintptr_t)text, (uint32_t)len};
  (void)semihost_call(kSysWrite, args);
}

void bms_semihost_exit(int status) {
  const uint32_t args[2] = {kAdpStoppedApplicationExit, (uint32_t)status};
  (void)semihost_call(kSysExitExtended, args);
  for (;;) {
  }
}
