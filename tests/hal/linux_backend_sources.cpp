// test_hal links bms_hal_fake and bms_firmware but not bms_hal_linux (tests/CMakeLists.txt),
// so the Linux backend is compiled into the test through this file. If bms_hal_linux is
// ever added to test_hal's libraries, delete this file.
#include "../../hal/linux/file_nvm.cpp"
#include "../../hal/linux/linux_clock.cpp"
#include "../../hal/linux/socketcan.cpp"
#include "../../hal/linux/stderr_log.cpp"
#include "../../hal/linux/timerfd_tick.cpp"
