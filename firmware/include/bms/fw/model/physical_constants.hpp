#pragma once
// CODATA 2018 exact values; one definition for the firmware and the host simulator.
namespace bms::fw {

inline constexpr double kFaradayC_mol = 96485.33212;
inline constexpr double kGasJ_molK = 8.314462618;

}  // namespace bms::fw
