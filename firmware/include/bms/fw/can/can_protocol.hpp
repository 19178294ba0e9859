// The BMS CAN protocol, all parts: the signal table (can_signal_table.hpp), the message
// values and their bindings (can_messages.hpp), the table-driven codec (can_codec.hpp),
// the transmitter (can_transmitter.hpp) and the validating receiver with the lock-step
// tick trigger (can_receiver.hpp). firmware/can/bms.dbc describes the same table;
// tests/hal/test_dbc.cpp checks it.
#pragma once

#include "bms/fw/can/can_codec.hpp"
#include "bms/fw/can/can_messages.hpp"
#include "bms/fw/can/can_receiver.hpp"
#include "bms/fw/can/can_signal_table.hpp"
#include "bms/fw/can/can_transmitter.hpp"
