#pragma once
// Design-time calibration of the firmware's reduced model (ReducedCell<PaperCellTraits, the
// default mesh>) against a converged DFN of the *nominal* paper cell: the model's voltage bias
// in CC charge per ampere of charge current, median over the charges after the 600 s warm-up.
// It uses the nominal cell only (no cell in use, no truth run of a study), like every other
// constant the firmware carries. Regenerate: scripts/calibrate-model-bias.sh (the command and the
// measured value are in docs/results/blind.md).
namespace bms::fw {

inline constexpr double kPaperReducedModelBiasOhm = 3.361195e-05;  // 0.084 mV at 2.5 A

}  // namespace bms::fw
