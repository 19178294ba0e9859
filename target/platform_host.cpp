// Host (Linux) side of platform.hpp: no instruction counter.
#include "platform.hpp"

#include <cstdio>

namespace bms::target {

void platform_start() {}
std::uint64_t platform_instructions() { return 0u; }
void platform_report() { std::printf("# platform host\n"); }

}  // namespace bms::target
