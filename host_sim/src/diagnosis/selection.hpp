#pragma once
// Choosing the effect from the candidates' held-out scores: the best one, or `none` when no
// candidate improves the held-out error meaningfully or when two different effects explain
// the residual equally well (the data cannot tell them apart: answering would be a guess).
#include <string>
#include <vector>

#include "diagnosis/effects.hpp"

namespace bms::diagnosis {

struct CandidateScore {
  Effect effect = Effect::none;
  bool available = true;
  double value = 0.0;           // fitted on the training part
  double heldout_rmse_mv = 0.0; // score: lower is better
};

struct SelectionRules {
  // The best candidate must cut the held-out RMSE of the plain model by this share...
  double min_relative_gain = 0.2;
  // ... and by at least this much in absolute terms (below it is noise and mesh error).
  double min_absolute_gain_mv = 0.05;
  // Two effects tie when what they leave is within the noise of each other: the structured
  // residual the best one leaves above the floor, sqrt(rmse^2 - floor^2), is at least
  // (1 - tie_share) of the second's, or the two differ by less than tie_floor_share of the
  // floor. The decision is on what is left, not on what is gained: two candidates that both
  // remove most of a large residual are not a tie when one leaves 5x less than the other.
  double tie_share = 0.25;
  double tie_floor_share = 0.5;
  // One constant current only: contact resistance and hysteresis both shift the voltage by a
  // constant, sensor offset and gain both scale the current, so a win of one over its twin
  // would rest on details (the initial hysteresis branch), not on the data.
  bool constant_current_only = false;
  // The residual's floor (noise and numerical error): held-out RMSEs are compared by what they
  // leave above it, sqrt(rmse^2 - floor^2), so two fits at the floor are not a tie when one
  // still leaves a structured part.
  double floor_mv = 0.0;
};

// The effect that leaves the same residual as e at one constant current (none if there is none).
Effect constant_current_twin(Effect e);

struct Selection {
  Effect effect = Effect::none;
  double value = 0.0;
  std::string reason;
  Effect best = Effect::none;  // the best candidate even when not chosen
  bool identifiable = true;    // false: a tie or a constant-current twin stopped the choice
};

Selection select_effect(double heldout_none_mv, const std::vector<CandidateScore>& candidates,
                        const SelectionRules& rules = {});

}  // namespace bms::diagnosis
