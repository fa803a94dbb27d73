// The simulated controller's wire and link (the model: sim_controller.cpp, 1, 3 and 6): bytes out,
// DC1/DC3 flow control and a late DC3, connections and link drops, reception at the line's rate.

#include "sim/sim_impl.hpp"

#include <algorithm>

#include "core/number_text.hpp"

namespace ncd::comms {

namespace {

// A DC3 sent this much after it was due (a late wake-up of the loop, a late write) pauses the wire
// until it has gone out (drip), so that the loop's own lateness is never blamed on the sender.
constexpr double kLateFlowS = 0.002;

}  // namespace

// Queues bytes for the sender (dropped while the link is down).
void SimController::Impl::send(std::string_view bytes) {
  if (port.is_open()) out.append(bytes);
}

void SimController::Impl::send_flow(bool xoff) {
  send(std::string(1, xoff ? kXoff : kXon));
  ++(xoff ? log.xoff_sent : log.xon_sent);
  told_xoff = xoff;
}

// A reply to `line`, unless it came on a connection that has since gone.
void SimController::Impl::reply(const Line& line, std::string_view text) {
  if (line.epoch == reply_epoch) send(text);
}

void SimController::Impl::flush_out() {
  if (out.empty() || !port.is_open()) return;
  const std::optional<std::size_t> written = port.write(out);
  if (!written) {  // the pty failed: what waited is lost
    out.clear();
    xoff_at_out.reset();
    return;
  }
  const std::size_t n = *written;
  if (n > 0) {
    out.erase(0, n);
    bytes_sent += n;
    if (xoff_at_out) {
      if (*xoff_at_out < n) {
        xoff_written(now_s());
      } else {
        *xoff_at_out -= n;
      }
    }
  }
}

// Drip: the flow control's DC3 has reached the sender, at t. A loop kept from running between
// the DC3's decision (at xoff_due_t) and its write (a loaded machine) let the sender go on
// writing meanwhile, which it could not have helped: a UART sends DC3 within a character
// time. What it wrote meanwhile waits until DC1, as its own flow control would have held it
// (the same rule as a DC3 found late while reading a burst, in receive()).
void SimController::Impl::xoff_written(double t) {
  xoff_at_out.reset();
  if (alarmed || !told_xoff) return;
  const double late_s = t - xoff_due_t;
  if (late_s <= kLateFlowS) return;
  hold_late_written(late_s);
}

// The characters the sender wrote while a DC3 was late by late_s (no more than the line could
// have carried meanwhile: a sender writing faster than the line gets no pass for the excess)
// obey DC3 until they have all been read.
void SimController::Impl::hold_late_written(double late_s) {
  const std::size_t waiting = backlog.size() + port.waiting();
  const auto could_send = static_cast<std::size_t>(late_s * cps) + 1;
  late_written_end = std::max(late_written_end, taken + std::min(waiting, could_send));
  ++log.xoff_late;
}

// The flow control at t: DC3 at high water (and in storms and holds), DC1 at low water.
void SimController::Impl::flow(double t) {
  if (!xon_xoff || !port.is_open() || alarmed) return;
  if (!fill_xoff && fill >= xoff_at) fill_xoff = true;
  if (fill_xoff && fill <= xon_at) fill_xoff = false;
  const bool want = fill_xoff || storm_until.has_value() || hold_until.has_value();
  if (want == told_xoff) return;
  send_flow(want);
  xoff_at_out.reset();
  if (want && !out.empty()) {  // its write is timed (flush_out)
    xoff_at_out = out.size() - 1;
    xoff_due_t = t;
  }
}

void SimController::Impl::on_slave_events(double t) {
  for (const Pty::SlaveEvent ev : port.take_slave_events()) {
    if (ev == Pty::SlaveEvent::Opened) {
      if (open_count++ == 0) sender_connected(t);
    } else if (open_count > 0 && --open_count == 0) {
      sender_disconnected(t);
    }
  }
}

void SimController::Impl::sender_connected(double t) {
  ++log.sender_connects;
  link_event(t, "sender_connected");
  port.flush_input();  // nothing stale for the new sender
  out.clear();
  xoff_at_out.reset();
  if (xon_xoff) send_flow(told_xoff);
  if (!drip && cfg.reset_on_open) reset(t, "port_opened");
}

void SimController::Impl::sender_disconnected(double t) {
  ++log.sender_disconnects;
  link_event(t, "sender_disconnected");
  port.flush_input();
  out.clear();
  xoff_at_out.reset();
  ++reply_epoch;
  // What it wrote is in the kernel; read it all now (a read, unlike FIONREAD, also waits for
  // the pty's flip buffer), so that the new sender's bytes, which follow, are told apart.
  for (;;) {
    const std::size_t n = port.read(buf.data(), buf.size());
    if (n == 0) break;
    backlog.append(buf.data(), n);
  }
  marker = taken + backlog.size();
  if (backlog.empty()) apply_marker();
}

// The bytes of a sender that went away have all been read: forget its unfinished line.
void SimController::Impl::apply_marker() {
  // grbl's UART knows nothing of the other end: a half line stays in its line buffer, and the
  // next bytes, from whichever connection, complete it (docs/dnc-link.md, "A half line").
  if (drip) discard_partial();
  rx_epoch = reply_epoch;
  blocks_in_epoch = 0;
  marker.reset();
}

void SimController::Impl::discard_partial() {
  if (!partial.empty()) ++log.partial_lines_discarded;
  fill -= static_cast<int>(partial.size());
  partial.clear();
  discarding_long = false;
}

void SimController::Impl::drop_link(double t) {
  drop_pending = false;
  link_event(t, "down");
  port.close();
  ++log.link_drops;
  event("link down after " + std::to_string(log.blocks_received) + " blocks (fault injection); " +
        cfg.line.device + " back in " + text::sig(cfg.faults.down_s) + " s");
  down_until = t + cfg.faults.down_s;
  out.clear();
  xoff_at_out.reset();
  backlog.clear();  // in flight when the line went down
  late_written_end = 0;
  ++reply_epoch;
  open_count = 0;
  rx_idle = true;
  credit = 0.0;
  apply_marker();
}

void SimController::Impl::restore_link(double t) {
  down_until.reset();
  port.open();
  link_event(t, "up");
  event(cfg.line.device + " -> " + port.device() + " again");
}

void SimController::Impl::receive(double t, bool readable) {
  if (!port.is_open()) return;
  if (marker && taken >= *marker) apply_marker();
  if (told_xoff && taken < late_written_end) {  // held as the sender would have held it
    credit = 0.0;
    credit_t = t;
    return;
  }
  if (rx_idle) {
    if (!readable && backlog.empty()) return;
    rx_idle = false;  // the first character's frame starts now
    credit = 0.0;
    credit_t = t;
    if (log.bytes_received == 0) log.first_byte_t_s = t;
    return;
  }
  const double credit_0 = credit, credit_t0 = credit_t;  // for each character's own time
  credit += (t - credit_t) * cps;
  credit_t = t;
  if (credit < 1.0) return;
  std::size_t want = std::min(buf.size(), static_cast<std::size_t>(credit));
  if (marker) want = std::min<std::size_t>(want, *marker - taken);
  if (want == 0) {
    apply_marker();
    return;
  }
  std::size_t got = std::min(want, backlog.size());
  if (got > 0) {
    std::copy_n(backlog.begin(), got, buf.begin());
    backlog.erase(0, got);
  }
  if (got < want) got += port.read(buf.data() + got, want - got);
  credit -= static_cast<double>(got);
  taken += got;
  for (std::size_t i = 0; i < got && !drop_pending; ++i) {
    if (!drip) {
      on_byte(buf[i], t);
      continue;
    }
    // Drip: the characters of a late wake-up arrived one frame apart, and the controller ran
    // and flowed meanwhile, as a UART's interrupt would have had it (the jitter of this loop is
    // the simulation's, not the controller's).
    const double t_i = std::min(t, credit_t0 + (static_cast<double>(i) + 1.0 - credit_0) / cps);
    execute(t_i);
    on_byte(buf[i], t_i);
    const bool was_xoff = told_xoff;
    flow(t_i);
    const std::uint64_t taken_here = taken - got + i + 1;
    const bool late = t - t_i > kLateFlowS;
    if (told_xoff && !was_xoff && (late || taken_here < late_written_end)) {
      // The DC3 was due at t_i and goes out only now: the sender could not have stopped. What
      // it wrote before it could see the DC3 waits, as its own flow control would have held
      // it, and obeys each DC3 until it has all been read.
      const std::size_t rest = got - i - 1;
      backlog.insert(0, buf.data() + i + 1, rest);
      taken = taken_here;
      credit = 0.0;
      if (late) hold_late_written(t - t_i);
      xoff_due_t = t;  // the rest of its lateness, until the write, is the write's
      break;
    }
  }
  if (drop_pending) {
    drop_link(t);
    if (restart_pending) {
      restart_pending = false;
      reset(t, "power_cycle");  // its banner goes out while the port is closed
    }
    return;
  }
  if (marker && taken >= *marker) apply_marker();
  if (got < want) {  // drained: the line is idle until the next character
    rx_idle = true;
    credit = 0.0;
  }
}

}  // namespace ncd::comms
