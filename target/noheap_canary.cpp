// Breaks the firmware rules on purpose: an allocation and an operator new. Compiled (never
// linked) so that ctest can show that target/tools/noheap_check.py notices (test
// target_noheap_detects_canary, expected to fail).
#include <cstddef>
#include <cstdlib>
#include <new>

void* bms_noheap_canary_malloc(std::size_t n) { return std::malloc(n); }
int* bms_noheap_canary_new() { return new int(1); }
