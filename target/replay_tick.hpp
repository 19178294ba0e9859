// The firmware as the target test application uses it: the tick (bms::fw::BmsCore over the
// reduced-order model, bms::fw::ReducedCell) and the one call per 0.2 s tick.
//
// This file and replay_tick.cpp are the whole firmware in the image: the heap, unwinding and
// stack checks of target/tools look at replay_tick.cpp's object (the firmware is header-only,
// so its code is instantiated there). BMS_REPLAY_SCALAR (double or float) is the build's
// scalar type: the host and Cortex-M7 builds use double, the Cortex-M4F build float.
#pragma once

#include <bms/fw/config/cell_choice.hpp>
#include <bms/fw/config/make_config.hpp>
#include <bms/fw/estimation/bms_core.hpp>
#include <bms/fw/model/reduced_cell.hpp>

#ifndef BMS_REPLAY_SCALAR
#define BMS_REPLAY_SCALAR double
#endif

namespace bms::target {

using Scalar = BMS_REPLAY_SCALAR;
/// The build's cell (CMake BMS_CELL, bms/fw/config/cell_choice.hpp): paper by default.
using Cell = bms::fw::SelectedCell;
using Model = bms::fw::ReducedCell<Scalar, Cell::Traits, Cell::Mesh>;
/// The profile the images are built for; its film path is fixed at build time (CoreFor).
inline constexpr bms::fw::Profile kProfile = bms::fw::Profile::best;
using Core = bms::fw::CoreFor<kProfile, Scalar, Model>;
static_assert(bms::fw::runs_path_of<Core>(kProfile), "the image's core runs its profile's film path");
using TickOutput = Core::Output;

/// The board's configuration: make_config over the build cell's nominal cell, profile kProfile.
Core::Config firmware_config();
/// The configuration `bmssim estimate` runs a cycler record with (the same make_config and
/// adapt_to_sample_step): the profile kProfile, the model tick dt_s, the record's sample step
/// when coarser than the tick (else 0), learning on or off (the control run).
Core::Config record_config(double dt_s, double sample_step_s, bool learning);
/// The model at the cell's initial state.
Model initial_firmware_model();

/// Everything the firmware owns: the main-system model and the core that drives it.
/// The build cell's best profile; the model starts from the cell's initial state.
struct ReplayFirmware {
  ReplayFirmware();
  explicit ReplayFirmware(const Core::Config& config);
  Model model;
  Core core;
};

/// The firmware's per-tick entry point as the application calls it: one measured sample
/// (voltage [V], current [A], positive on discharge) in, the tick's estimates out.
TickOutput replay_tick(ReplayFirmware& fw, Scalar voltage_v, Scalar current_a);
/// The same with the measured cell temperature [K] (0: none measured this tick; the model keeps
/// the last accepted one, at power-up the cell's reference temperature).
TickOutput replay_tick(ReplayFirmware& fw, Scalar voltage_v, Scalar current_a, Scalar temperature_k);

/// Bounded worst case of the tick's model step: the voltage-driven (CV) step of a copy of the
/// model, asked for a terminal voltage it cannot reach, so that its Newton iteration runs
/// into kMaxNewtonIterations. Returns the step's result; the firmware is not changed.
bms::fw::ModelTickResult<Scalar> newton_cap_probe(const ReplayFirmware& fw);

/// Cost of the beyond-paper state re-synchronisation (once per CV phase): a copy of the model
/// re-synchronised to 5 mV above its own voltage at 0.2 A and 0.5 % more lithium, so that the
/// regula falsi has to work. Returns whether it converged; the firmware is not changed.
bool resync_probe(const ReplayFirmware& fw);

/// The tick in which samples return after `gap` ticks without one (the catch-up,
/// BmsCore::Config::catch_up_max_steps). Changes the firmware: call it last.
TickOutput catch_up_probe(ReplayFirmware& fw, unsigned gap, Scalar voltage_v, Scalar current_a);

}  // namespace bms::target
