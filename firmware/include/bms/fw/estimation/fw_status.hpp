#pragma once
// Firmware status bits: one 32-bit word, each module owns a fixed range of bits so that
// words from several modules can be OR-ed into one diagnostic word without collisions.
//
// Bit ranges (allocate further modules in blocks of 8; never renumber a published bit, since
// status words are logged and stored in non-volatile memory):
//   bits  0.. 7  state estimation: RCSI estimator and its RLS core (this file, below)
//   bits  8..15  the tick (bms/fw/estimation/bms_core.hpp): input validation and the main-system model
//   bits 16..23  the operating envelope: measured temperature, model validity (below)
//   bits 24..31  reserved for other firmware modules (not allocated yet)
#include <cstdint>

namespace bms::fw {

using StatusWord = std::uint32_t;

enum class FwStatus : StatusWord {
  kNone = 0u,
  // --- RCSI / RLS estimator: bits 0..7 -------------------------------------------------
  // A non-finite input (z, y0_hat) or a non-finite retrospective target u*: the learning
  // step was skipped (theta and P unchanged).
  kRejectedNonFinite = 1u << 0,
  // The estimated subsystem output u_hat was clipped to the configured [min, max] range.
  kOutputClipped = 1u << 1,
  // trace(P) exceeded its cap after an update; P was scaled down to the cap.
  kCovarianceCapped = 1u << 2,
  // An update produced a non-finite theta or P (or a non-positive gain denominator); the
  // result was discarded and the last good theta and P were kept.
  kThetaRestored = 1u << 3,
  // Call-order violation: update() without a preceding predict() (the call was ignored).
  kCallOrder = 1u << 4,
  // Invalid configuration, or a rejected restore()/set_*() argument (nothing was changed).
  kConfigInvalid = 1u << 5,
  // theta^T phi was not finite (overflow); the previous u_hat was held instead.
  kPredictionNonFinite = 1u << 6,
  // bit 7: spare, reserved for the estimator.
  // --- Tick: bits 8..15 ----------------------------------------------------------------
  // The sample was rejected (state kept): a measurement was NaN or infinite.
  kSampleNonFinite = 1u << 8,
  // The sample was rejected: voltage outside the plausible range (default 0..5 V).
  kVoltageOutOfRange = 1u << 9,
  // The sample was rejected: |current| above its limit, or a current step between two
  // ticks larger than any the cell can carry.
  kCurrentImplausible = 1u << 10,
  // No valid measurement for more than the allowed number of ticks: estimation frozen.
  kMeasurementStale = 1u << 11,
  // The voltage-driven (CV) model step hit its Newton iteration cap.
  kModelNotConverged = 1u << 12,
  // The model produced a non-finite state; the tick was not committed.
  kModelInvalid = 1u << 13,
  // A saved state was rejected on restore (layout or content).
  kRestoreRejected = 1u << 14,
  // The state re-synchronisation at the end of a CV phase found no admissible state; the
  // model state was kept as it was.
  kResyncFailed = 1u << 15,
  // --- Operating envelope: bits 16..23 --------------------------------------------------
  // The measured temperature was non-finite or outside the model's range: the model kept the
  // last accepted temperature (the sample itself was used).
  kTemperatureImplausible = 1u << 16,
  // The innovation test of a learning tick failed (BmsCore::Config::innovation_*): the model's
  // residual, averaged, is beyond what its own error explains; the estimate is not to be trusted.
  kModelMisfit = 1u << 17,
  // The identifier did not learn from this tick: its regression's averaged a-priori innovation
  // failed the consistency check (IdentifierFilmPath::Config::innovation_rejects).
  kInnovationRejected = 1u << 18,
};

inline constexpr StatusWord kTickRejectMask = (1u << 8) | (1u << 9) | (1u << 10);

inline constexpr StatusWord kEstimatorStatusMask = 0x000000FFu;

constexpr StatusWord bit(FwStatus s) { return static_cast<StatusWord>(s); }

constexpr bool has_status(StatusWord word, FwStatus s) { return (word & bit(s)) != 0u; }

}  // namespace bms::fw
