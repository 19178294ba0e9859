/*
 * LD_PRELOAD shim for Debian's User-Mode Linux (linux.uml 6.1) on hosts whose CPU has a
 * larger XSAVE area than UML's fixed floating-point buffer (AMX: 11008 bytes vs 2696).
 *
 * Why: UML saves a guest thread's FP state with ptrace(PTRACE_GETREGSET, NT_X86_XSTATE)
 * into a buffer of 2696 bytes (the kernel truncates, fine) and restores it with
 * PTRACE_SETREGSET of the same 2696 bytes. The host kernel accepts SETREGSET only with the
 * whole user XSAVE size (arch/x86/kernel/fpu/regset.c: count != fpu_user_cfg.max_size
 * -> -EFAULT), so the first context switch fails: "userspace - ptrace set fp regs
 * failed, errno = 14" and init is killed.
 *
 * What: on a short SETREGSET this reads the target's whole current XSAVE state, lays
 * UML's bytes over its beginning and keeps, for every state component that lies (partly)
 * beyond UML's buffer, the target's current value and header bit. UML's buffer covers
 * x87/SSE/AVX/AVX-512/PKRU, so guest programs keep all of those; the components past it
 * (AMX tiles) are ones a UML guest cannot enable anyway. When the sizes already match
 * (older CPUs) every call goes straight through.
 *
 * Build: cc -shared -fPIC -O2 -o uml-xstate-shim.so uml-xstate-shim.c -ldl
 * Use:   LD_PRELOAD=/path/uml-xstate-shim.so linux.uml ...
 * Set VCAN_RUN_SHIM_LOG=1 to print the sizes once on stderr.
 */
#define _GNU_SOURCE
#include <cpuid.h>
#include <dlfcn.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/ptrace.h>
#include <sys/types.h>
#include <sys/uio.h>

#ifndef NT_X86_XSTATE
#define NT_X86_XSTATE 0x202
#endif

#define XSAVE_HDR_OFFSET 512
#define XSAVE_HDR_END 576
#define XBUF_MAX (64 * 1024)

typedef long (*ptrace_fn)(int, pid_t, void *, void *);

/* UML is single-threaded where it calls ptrace, and runs this on its small kernel stacks:
   keep the big buffer static, never on the stack. */
static unsigned char full_buf[XBUF_MAX] __attribute__((aligned(64)));
static ptrace_fn real_ptrace;
static uint32_t comp_end[64]; /* standard-format end offset of component i, 0 if absent */
static size_t full_size;      /* host's whole user XSAVE size, 0 until known */
static int log_once;

static void init_components(void)
{
  for (unsigned i = 2; i < 64; i++) {
    unsigned a = 0, b = 0, c = 0, d = 0;
    if (__get_cpuid_count(0xd, i, &a, &b, &c, &d) && a != 0 && !(c & 1)) /* user comps */
      comp_end[i] = b + a;
  }
}

long ptrace(enum __ptrace_request req, ...)
{
  va_list ap;
  va_start(ap, req);
  pid_t pid = va_arg(ap, pid_t);
  void *addr = va_arg(ap, void *);
  void *data = va_arg(ap, void *);
  va_end(ap);
  if (!real_ptrace) {
    real_ptrace = (ptrace_fn)dlsym(RTLD_NEXT, "ptrace");
    init_components();
  }
  if (req != PTRACE_SETREGSET || (uintptr_t)addr != NT_X86_XSTATE || !data)
    return real_ptrace(req, pid, addr, data);

  struct iovec *iov = data;
  size_t len = iov->iov_len;
  if ((full_size && len >= full_size) || len < XSAVE_HDR_END)
    return real_ptrace(req, pid, addr, data);

  struct iovec fiov = {full_buf, sizeof full_buf};
  if (real_ptrace(PTRACE_GETREGSET, pid, addr, &fiov) < 0)
    return -1;
  full_size = fiov.iov_len;
  if (!log_once) {
    log_once = 1;
    if (getenv("VCAN_RUN_SHIM_LOG"))
      fprintf(stderr, "uml-xstate-shim: UML buffer %zu bytes, host XSAVE %zu bytes\n", len,
              full_size);
  }
  if (len >= full_size)
    return real_ptrace(req, pid, addr, data);

  uint64_t cur_bv, bv;
  memcpy(&cur_bv, full_buf + XSAVE_HDR_OFFSET, sizeof cur_bv);
  memcpy(full_buf, iov->iov_base, len);
  memcpy(&bv, full_buf + XSAVE_HDR_OFFSET, sizeof bv);
  for (unsigned i = 2; i < 64; i++)
    if (comp_end[i] > len)
      bv = (bv & ~(1ull << i)) | (cur_bv & (1ull << i));
  memcpy(full_buf + XSAVE_HDR_OFFSET, &bv, sizeof bv);
  return real_ptrace(req, pid, addr, &fiov);
}
