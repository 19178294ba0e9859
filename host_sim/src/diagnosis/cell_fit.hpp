#pragma once
// `bmssim fit`: a cell's parameters from its cycler data, starting from a template BPX file.
// The truth DFN (run_model) is run on the measured current; a Levenberg-Marquardt search on
// the training rows moves the parameters the data can identify (electrode balance: electrode
// area, positive capacity and the negative electrode's stoichiometry at the upper voltage;
// series resistance as the initial SEI film; solid diffusivities; reaction rate constants;
// electrolyte conductivity), each candidate cell written as BPX and read back by the same
// reader every --cell uses, so the fitted cell is exactly the one written. Standard errors:
// (J^T J)^-1 s^2 at the optimum (J by finite differences, s^2 the residual variance). A
// parameter the data cannot tell (a Jacobian column too small, nearly collinear with the
// others, or a relative sd too large) is not fitted and keeps the template's value. Optionally
// an additive correction to the positive electrode's open-circuit potential (knots in volts,
// piecewise linear in stoichiometry), written into the BPX file as the template's OCP plus the
// correction, exactly.
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cell/cell_parameters.hpp"
#include "dfn/dfn_model.hpp"
#include "diagnosis/records.hpp"

namespace bms::diagnosis {

// Rows of the data the model runs through from one initial state (a rest voltage or the
// cell's full state): a record, or a part of one after a long rest (re-synchronised there).
struct FitPiece {
  Record record;
  std::vector<int> cycle;  // per row
  std::vector<char> role;  // per row: 0 not used, 1 training, 2 held out
};
inline constexpr char kRoleTrain = 1;
inline constexpr char kRoleHeldOut = 2;

// The positive electrode's open-circuit correction: at most this many knots.
inline constexpr int kMaxOcpKnots = 8;

struct CellFitSettings {
  DfnMesh search_mesh{8, 8, 8, 8};   // the fit's runs
  DfnMesh final_mesh{20, 20, 20, 20};  // scoring (the --cell default mesh)
  double rtol = 1e-6;
  int max_iterations = 12;
  double v_min = std::numeric_limits<double>::quiet_NaN();  // the fitted cell's window
  double v_max = std::numeric_limits<double>::quiet_NaN();
  double max_relative_sd = 0.5;     // above: not identifiable
  double max_collinearity = 0.99;   // |cos| of a column to the span of the others
  double min_sensitivity_mv = 0.2;  // RMS voltage change for a change of 1 in the parameter's unit of search
  // An additive correction to the positive electrode's OCP, piecewise linear in its stoichiometry
  // through this many knots spread evenly over the template's positive window at the data's
  // voltage window (0: none; else 2..kMaxOcpKnots); each knot a parameter in volts.
  int ocp_knots = 0;
  double max_ocp_sd_mv = 10.0;  // a knot's sd above this (absolute: the knot is additive): not identifiable
  std::vector<std::string> only;    // non-empty: fit only these names
  // > 0: the largest charge (Ah) one discharge of the training rows delivered; the search starts
  // from the electrode area that gives the template's window this capacity.
  double measured_capacity_ah = 0.0;
};

struct FitParameter {
  std::string name, unit, meaning;
  double template_value = 0.0, value = 0.0;
  double sd = std::numeric_limits<double>::quiet_NaN();  // NaN: not fitted
  bool fitted = false;
  std::string note;  // why not fitted
};

// Where a piece's model run stopped before the piece's last scored row, and why.
struct ModelStop {
  std::size_t piece = 0, row = 0, rows = 0;  // row: the first row not reached (0-based in the piece), of rows
  int cycle = 0;
  double t_s = 0.0;
  std::string why;
};

// One cycle's voltage residual (model - measured) over the rows the model reached.
struct CycleScore {
  int cycle = 0;
  char role = 0;                   // kRoleTrain or kRoleHeldOut
  std::size_t samples = 0, scored = 0;  // rows of the cycle, rows the model reached
  double rmse_mv = std::numeric_limits<double>::quiet_NaN();
  double mean_mv = std::numeric_limits<double>::quiet_NaN();
  double max_abs_mv = std::numeric_limits<double>::quiet_NaN();
};

// A cell scored on pieces, each run from its own initial state (the measured rest voltage at its
// first row through the cell's open-circuit curve). Rows the model did not reach are not scored
// (NaN in voltage_v) and are counted: coverage = scored / samples.
struct CellScore {
  std::vector<std::vector<double>> voltage_v;  // per piece, per row; NaN where unused or not reached
  std::vector<CycleScore> cycles;
  std::vector<ModelStop> stops;
  std::vector<std::string> initial_states;  // per piece: how its initial state was set
  std::size_t train_samples = 0, train_scored = 0, heldout_samples = 0, heldout_scored = 0;
  double rmse_train_mv = std::numeric_limits<double>::quiet_NaN();
  double rmse_heldout_mv = std::numeric_limits<double>::quiet_NaN();
  double max_abs_heldout_mv = std::numeric_limits<double>::quiet_NaN();
};

// Runs `cell` on every piece (mesh, rtol) and scores the training and held-out rows.
CellScore score_cell(const CellParameters& cell, const std::vector<FitPiece>& pieces, const DfnMesh& mesh,
                     double rtol);

struct CellFitResult {
  std::string bpx_text;  // the fitted cell
  CellParameters cell;
  std::vector<FitParameter> parameters;
  nlohmann::json derived;  // voltage window, stoichiometry window, capacity
  CellScore fitted, templ;  // the final scores (the scoring pieces, final mesh)
  double rmse_template_train_mv = 0.0, rmse_train_mv = 0.0;
  double rmse_template_heldout_mv = std::numeric_limits<double>::quiet_NaN();
  double rmse_heldout_mv = std::numeric_limits<double>::quiet_NaN();
  double max_abs_heldout_mv = std::numeric_limits<double>::quiet_NaN();
  std::size_t train_samples = 0, heldout_samples = 0;
  int evaluations = 0, iterations = 0;
  double residual_sd_mv = 0.0;
  double rmse_objective_mv = 0.0;  // the search's training RMSE at the optimum (search mesh and pieces)
  std::vector<std::string> notes;
};

// template_bpx: the template's BPX JSON (its numbers, expressions or tables are scaled where fitted).
// search_pieces: the training rows the search runs on; score_pieces: every training and held-out
// row, in the pieces the final score runs (restarted at every state known from measurements).
CellFitResult fit_cell(const nlohmann::json& template_bpx, const std::string& template_name,
                       const std::vector<FitPiece>& search_pieces, const std::vector<FitPiece>& score_pieces,
                       const CellFitSettings& settings,
                       const std::function<void(const std::string&)>& log);

// Names of every parameter fit may move, in order.
std::vector<std::string> fit_parameter_names();

}  // namespace bms::diagnosis
