#include "bms/hal/fake/fake_can.hpp"

#include "bms/hal/fake/fake_time.hpp"

namespace bms::hal::fake {

FakeCanBus::FakeCanBus(std::size_t rx_capacity) : rx_capacity_(rx_capacity) {}

FakeCanBus::~FakeCanBus() { disconnect(); }

void FakeCanBus::connect(FakeCanBus& a, FakeCanBus& b) {
  a.disconnect();
  b.disconnect();
  a.peer_ = &b;
  b.peer_ = &a;
}

void FakeCanBus::disconnect() {
  if (peer_ != nullptr && peer_ != this && peer_->peer_ == this) peer_->peer_ = nullptr;
  peer_ = nullptr;
}

void FakeCanBus::drop_next(std::size_t n) {
  for (std::size_t i = 0; i < n; ++i) faults_.push_back({OneShot::drop, 0, 0});
}

void FakeCanBus::corrupt_next(std::size_t byte_index, std::uint8_t xor_mask) {
  faults_.push_back({OneShot::corrupt, byte_index, xor_mask});
}

void FakeCanBus::truncate_next(std::uint8_t len) { faults_.push_back({OneShot::truncate, 0, len}); }

void FakeCanBus::duplicate_next() { faults_.push_back({OneShot::duplicate, 0, 0}); }

Status FakeCanBus::send(const CanFrame& frame) {
  if (!can_frame_valid(frame)) {
    last_error_ = "fake CAN: invalid frame (id or length)";
    return Status::invalid_argument;
  }
  sent_.push_back(frame);
  if (send_status_ != Status::ok) {
    last_error_ = std::string("fake CAN: injected send failure: ") + status_name(send_status_);
    return send_status_;
  }
  CanFrame f = frame;
  FaultAction action = FaultAction::deliver;
  if (!faults_.empty()) {
    const PendingFault pf = faults_.front();
    faults_.pop_front();
    switch (pf.kind) {
      case OneShot::drop: action = FaultAction::drop; break;
      case OneShot::corrupt:
        if (pf.byte_index < sizeof f.data) f.data[pf.byte_index] = static_cast<std::uint8_t>(f.data[pf.byte_index] ^ pf.value);
        break;
      case OneShot::truncate: f.len = pf.value > kCanMaxLen ? kCanMaxLen : pf.value; break;
      case OneShot::duplicate: action = FaultAction::duplicate; break;
    }
  }
  if (hook_ && action != FaultAction::drop) {
    const FaultAction h = hook_(f);
    if (h != FaultAction::deliver) action = h;
  }
  if (action == FaultAction::drop || peer_ == nullptr) return Status::ok;  // lost on the wire
  // A full receive queue at the peer is the peer's overflow (rx_overflows()), not a send error.
  if (peer_->deliver(f) == Status::ok && action == FaultAction::duplicate) peer_->deliver(f);
  return Status::ok;
}

Status FakeCanBus::inject(const CanFrame& frame) { return deliver(frame); }

Status FakeCanBus::deliver(const CanFrame& frame) {
  if (!passes_filters(frame.id)) {
    ++filtered_out_;
    return Status::ok;
  }
  if (rx_.size() >= rx_capacity_) {
    ++rx_overflows_;
    return Status::overflow;
  }
  rx_.push_back(frame);
  return Status::ok;
}

bool FakeCanBus::passes_filters(std::uint32_t id) const {
  if (accept_all_) return true;
  for (const CanFilter& f : filters_)
    if (can_filter_match(f, id)) return true;
  return false;
}

Status FakeCanBus::receive(CanFrame& frame, std::int32_t timeout_ms) {
  if (rx_.empty()) {
    if (clock_ != nullptr && timeout_ms > 0) clock_->advance_ns(static_cast<std::uint64_t>(timeout_ms) * 1'000'000u);
    return Status::timeout;
  }
  frame = rx_.front();
  rx_.pop_front();
  return Status::ok;
}

Status FakeCanBus::set_filters(const CanFilter* filters, std::size_t count) {
  if (count > kCanMaxFilters || (count > 0 && filters == nullptr)) {
    last_error_ = "fake CAN: too many filters";
    return Status::invalid_argument;
  }
  filters_.assign(filters, filters + count);
  accept_all_ = false;
  return Status::ok;
}

}  // namespace bms::hal::fake
