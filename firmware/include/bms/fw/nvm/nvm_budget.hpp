// The flash write budget: how often the estimator's state may be committed so that the
// flash outlives the device.
//
// Every commit erases and writes one slot of the two-slot RecordStore (nvm_store.hpp), so
// each slot's pages see one program/erase cycle per two commits. A flash rated for E cycles
// per page, used for L seconds, allows 2 E commits over the life; spread evenly that is one
// commit every L / (2 E) seconds. Worked figures (0.2 s ticks):
//   E = 10 000 (a typical MCU data flash), L = 10 years: one commit per 4.4 h (78 894 ticks)
//   one commit per 60 s instead would wear such a flash out in 2 E * 60 s = 13.9 days.
// The budget is a credit in ticks (a token bucket): it grows by one per tick, up to
// burst_commits commits' worth, and a commit spends one interval. So commits can come close
// together when they matter (the end of a charge, a shutdown), but over any span T there are
// at most burst_commits + T / interval of them; the interval is computed with the burst taken
// out of the life's total, so the bound holds over the whole lifetime. The credit is saved
// with the state (a power cycle does not refill it) and does not grow while the device is off.
//
// Header-only C++17: no heap, no exceptions, no RTTI.
#pragma once

#include <cstdint>

namespace bms::fw::nvm {

struct WriteBudgetConfig {
  double endurance_cycles = 10000.0;  ///< rated program/erase cycles per page
  double lifetime_s = 10.0 * 365.25 * 86400.0;
  double tick_s = 0.2;
  std::uint32_t slots = 2;          ///< commits per erase cycle of one slot's pages
  std::uint32_t burst_commits = 4;  ///< commits allowed back to back
};

class WriteBudget {
 public:
  WriteBudget() : WriteBudget(WriteBudgetConfig{}) {}
  explicit WriteBudget(const WriteBudgetConfig& c) : interval_ticks_(interval_for(c)), burst_(c.burst_commits) {
    credit_ = cap();
  }

  /// Ticks between commits on average (0: no budget, every commit allowed).
  static std::uint32_t interval_for(const WriteBudgetConfig& c) {
    const double commits = c.endurance_cycles * static_cast<double>(c.slots) - static_cast<double>(c.burst_commits);
    if (!(commits > 0.0) || !(c.tick_s > 0.0) || !(c.lifetime_s > 0.0)) return 0xFFFFFFFFu;
    const double ticks = c.lifetime_s / commits / c.tick_s;
    if (ticks >= 4294967295.0 / static_cast<double>(c.burst_commits + 1u)) return 0xFFFFFFFFu / (c.burst_commits + 1u);
    return ticks < 1.0 ? 0u : static_cast<std::uint32_t>(ticks + 0.999999);
  }

  /// One tick passed (credit grows, up to burst_commits intervals).
  void tick(std::uint32_t ticks = 1u) {
    const std::uint32_t c = cap();
    credit_ = (c - credit_ < ticks) ? c : credit_ + ticks;
  }
  /// True (and the credit spent) when a commit is allowed now.
  bool try_spend() {
    if (credit_ < interval_ticks_) {
      ++refused_;
      return false;
    }
    credit_ -= interval_ticks_;
    return true;
  }

  std::uint32_t interval_ticks() const { return interval_ticks_; }
  std::uint32_t credit_ticks() const { return credit_; }
  std::uint32_t refused() const { return refused_; }
  /// The credit saved with the state; a stored value above the cap is cut to it.
  void restore_credit(std::uint32_t credit_ticks) { credit_ = credit_ticks < cap() ? credit_ticks : cap(); }

 private:
  std::uint32_t cap() const { return interval_ticks_ * burst_; }

  std::uint32_t interval_ticks_;
  std::uint32_t burst_;
  std::uint32_t credit_ = 0;
  std::uint32_t refused_ = 0;
};

}  // namespace bms::fw::nvm
