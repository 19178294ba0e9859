// Everything the firmware core may use from the hardware-abstraction layer.
#pragma once

#include "bms/hal/can_bus.hpp"
#include "bms/hal/lockstep.hpp"
#include "bms/hal/log_sink.hpp"
#include "bms/hal/monotonic_clock.hpp"
#include "bms/hal/nvm.hpp"
#include "bms/hal/status.hpp"
#include "bms/hal/tick_source.hpp"
#include "bms/hal/watchdog.hpp"
