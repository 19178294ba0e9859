// The estimator's state in non-volatile memory: restored at start-up, committed at the end of
// every constant-current charge (the estimate just learned) and on a timer, every commit
// within the flash write budget (fw::nvm::WriteBudget), two slots with a CRC each
// (fw::nvm::RecordStore). Portable: no heap, no exceptions, no RTTI.
#pragma once

#include <cstdint>

#include "bms/fw/nvm/nvm_budget.hpp"
#include "bms/fw/nvm/nvm_store.hpp"
#include "bms/fw/nvm/state_schema.hpp"
#include "bms/hal/nvm.hpp"

namespace bms::app {

template <class Core>
class StatePersistence {
 public:
  // What survives a power cut: the core's state, the tick it belongs to (so that after a
  // restart in lock-step the firmware knows how many ticks it missed; the core then steps its
  // model over them, BmsCore::Config::catch_up_max_ticks) and the write budget's credit (a
  // power cycle must not refill it).
  struct Persisted {
    typename Core::State core;
    std::uint32_t tick;
    std::uint32_t budget_credit_ticks;
  };
  // The record's layout tag: the schema hash of every saved field (state_schema.hpp). The
  // name in the hash is the one records were first written with: saved states stay readable.
  static constexpr std::uint32_t kPersistedTag = [] {
    using P = Persisted;
    constexpr fw::schema::Field f[] = {BMS_SCHEMA_NESTED(P, core, Core), BMS_SCHEMA_FIELD(P, tick),
                                       BMS_SCHEMA_FIELD(P, budget_credit_ticks)};
    static_assert(fw::schema::covers(f, sizeof(P), alignof(P)), "Persisted changed: update its schema table");
    return fw::schema::hash("BmsApplication.Persisted", f, sizeof(P));
  }();
  using Store = fw::nvm::RecordStore<Persisted, kPersistedTag, hal::NonVolatileMemory>;

  struct Options {
    // Timer commits: at most one per this many ticks (0: none); each within the budget.
    std::uint32_t persist_every_ticks = 78910;  // the default budget's interval (4.4 h)
    bool persist_at_charge_end = true;          // commit when a CC charge ends (within the budget)
    fw::nvm::WriteBudgetConfig budget{};
  };

  struct Counters {
    std::uint32_t commits = 0;
    std::uint32_t failures = 0;
    std::uint32_t refused_by_budget = 0;
  };

  enum class Loaded { none, restored, rolled_back, unreadable };

  StatePersistence(Core& core, hal::NonVolatileMemory& nvm, const Options& o)
      : core_(core), o_(o), store_(nvm, 0), budget_(o.budget) {}

  /// Loads the saved state into the core; `tick` is the tick the state belongs to.
  Loaded restore(std::uint32_t& tick) {
    const fw::nvm::StoreStatus s = store_.load(image_);
    if (s == fw::nvm::StoreStatus::ok && core_.restore(image_.core)) {
      budget_.restore_credit(image_.budget_credit_ticks);
      tick = image_.tick;
      if (store_.fell_back()) {
        failed_ = true;
        return Loaded::rolled_back;
      }
      return Loaded::restored;
    }
    if (s == fw::nvm::StoreStatus::empty) return Loaded::none;
    failed_ = true;
    return Loaded::unreadable;
  }

  /// Commits the state now if the write budget allows; true when committed. A refusal is not
  /// a fault (the last commit stays); a failed commit is one until the next good commit.
  bool commit(std::uint32_t tick) {
    if (!budget_.try_spend()) {
      ++counters_.refused_by_budget;
      return false;
    }
    image_.core = core_.save();
    image_.tick = tick;
    image_.budget_credit_ticks = budget_.credit_ticks();
    const bool ok = store_.save(image_) == fw::nvm::StoreStatus::ok;
    if (ok) {
      ++counters_.commits;
      failed_ = false;
      since_commit_ = 0;
      pending_ = false;
    } else {
      ++counters_.failures;
      failed_ = true;
    }
    return ok;
  }

  /// Once per tick, after the core's tick: `ticks` ticks passed (the missed ones included).
  /// Commits asked for by the end of a CC charge or by the timer stay pending until the
  /// write budget allows them.
  void after_tick(bool cc_charge, std::uint32_t ticks, std::uint32_t tick) {
    budget_.tick(ticks);
    if (o_.persist_at_charge_end && was_cc_charge_ && !cc_charge) pending_ = true;
    was_cc_charge_ = cc_charge;
    since_commit_ = since_commit_ + ticks < since_commit_ ? 0xFFFFFFFFu : since_commit_ + ticks;
    if (o_.persist_every_ticks != 0u && since_commit_ >= o_.persist_every_ticks) pending_ = true;
    if (pending_ && budget_.credit_ticks() >= budget_.interval_ticks()) commit(tick);
  }

  /// Asks for a commit at the next tick the budget allows (a reset state, for example).
  void request_commit() { pending_ = true; }

  /// The last load or commit failed (fault bit kNvm).
  bool failed() const { return failed_; }
  const Counters& counters() const { return counters_; }
  const fw::nvm::WriteBudget& write_budget() const { return budget_; }
  const Store& store() const { return store_; }

 private:
  Core& core_;
  Options o_;
  Store store_;
  fw::nvm::WriteBudget budget_;
  Counters counters_{};
  Persisted image_{};  // save/restore buffer: a member, not a stack object (it is large)
  std::uint32_t since_commit_ = 0;
  bool pending_ = false;
  bool was_cc_charge_ = false;
  bool failed_ = false;
};

}  // namespace bms::app
