// Ending early (docs/service.md). A streamed job that does not reach its end (stop, shutdown, a
// job error, a block the controller's dialect refuses, an exception) leaves the machine by the
// same sequence: the motion stops on the path (the cycle's jerk-limited stop), then the job's
// retract from where the blocks left the tool (toolpath::SafeRetract: for an inner edge back to
// the drill axis first, then up to the clearance plane), M5, M9 and the program end
// (comms::ending_blocks). Where the ending goes depends on the link:
//   - ack (grbl) with status polling: at the request, DncSender::end_with holds the controller
//     (`!`), waits for Hold:0, resets it (0x18) and sends the ending from where the hold left the
//     tool, so the controller does not run the seconds of blocks it had queued;
//   - drip (and ack without status): the ending is written into the block stream after the
//     planned stop's last block; the controller runs what it holds, then the ending.
// Every block is checked against the controller's dialect before it is queued (the check the
// sender repeats before writing it): a refused block and everything after it stay out of the
// queue, and the ending follows the last block queued. A link that ends while the motion runs
// (lost, given up, the controller's alarm) ends the job in error with the ending NOT sent, and
// the error says what to do at the machine (toolpath::retract_advice).
#include <string>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "service/service.hpp"
#include "service/service_live.hpp"

namespace ncd::service {

bool Service::ends_by_hold_and_reset() const {
  return live_ && live_->hold_and_reset;
}

std::string Service::ending_advice() const {
  if (!job_.retract) {
    return "at the machine: stop the motion, switch the spindle (M5) and the coolant (M9) off "
           "and retract the tool (the job has no retract of its own)";
  }
  return toolpath::retract_advice(*job_.retract);
}

void Service::request_ending(const std::string& why, bool now) {
  if (!live_ || ending_.state != EndingStatus::State::None) return;
  ending_.state = EndingStatus::State::Pending;
  const comms::EncoderSettings& enc = live_->encoder->settings();
  if (now && ends_by_hold_and_reset()) {
    ending_.how =
        "feed hold (!) at once, Hold:0, soft reset (0x18), then from where the hold left the "
        "tool: the retract, M5, M9, the program end";
    const std::optional<toolpath::SafeRetract> retract = job_.retract;
    const int decimals = enc.decimals, feed_decimals = enc.feed_decimals;
    live_->sender->end_with(
        [retract, decimals, feed_decimals](const std::optional<std::array<double, 3>>& at) {
          std::optional<Vec3> p;
          if (retract && at) p = Vec3((*at)[0], (*at)[1], (*at)[2]);
          return comms::ending_blocks(retract.value_or(toolpath::SafeRetract{}), p, decimals,
                                      feed_decimals, true);
        });
  } else {
    ending_.how =
        "after the planned stop on the path: the blocks up to the stop, then from there the "
        "retract, M5, M9, the program end";
    append_pending_ = true;
  }
  if (job_.retract) {
    ending_.how += "; clearance Z " + text::fixed(job_.retract->clearance_z_mm, 3) + " mm (" +
                   job_.retract->clearance_from + ")" +
                   (job_.retract->axis_xy ? ", in the bore back to the drill axis first" : "");
  } else {
    ending_.how += "; the job has no retract of its own: nothing moves";
  }
  log("ending job " + job_.name + " (" + why + "): " + ending_.how);
}

// The ending into the block stream, after the last block queued (the planned stop's, or the
// last before a refused one).
void Service::append_ending() {
  Live& l = *live_;
  if (l.ending_written) return;
  l.ending_written = true;
  append_pending_ = false;
  const comms::EncoderSettings& enc = l.encoder->settings();
  l.encoder->close_block();  // the planned stop's last block (left out after a refusal)
  l.writing_ending = true;
  const std::optional<Vec3> at = job_.retract ? l.queued_at : std::nullopt;
  const std::vector<std::string> words = comms::ending_blocks(
      job_.retract.value_or(toolpath::SafeRetract{}), at, enc.decimals, enc.feed_decimals, false);
  for (const std::string& w : words) l.encoder->words(w);
  l.encoder->finish();
  l.encoder->percent_line();
  l.writing_ending = false;
  ending_.blocks = l.ending_blocks;
  if (!l.ending_refused.empty()) ending_.note = "left out of the ending: " + l.ending_refused;
  if (!at && job_.retract) {
    ending_.note += (ending_.note.empty() ? "" : "; ") +
                    std::string("no move had been queued, so the ending moves nothing");
  }
}

// The sender has ended; the ending asked for either reached the controller or did not.
void Service::resolve_ending(const comms::SenderReport& r) {
  const std::string note = ending_.note;
  if (live_->hold_and_reset && !append_pending_ && !live_->ending_written) {
    const comms::EndingReport& e = r.ending;
    if (e.not_needed) {
      ending_.state = EndingStatus::State::NotNeeded;
      ending_.note = "no move had been sent: the controller never moved";
      return;
    }
    ending_.blocks = e.lines;
    if (e.sent && !e.position_doubt.empty() && e.held_at_mm) {
      // Reset (spindle and coolant off) and ended, but no retract: where the tool is, is not
      // known.
      ending_.state = EndingStatus::State::NotSent;
      char at[96];
      std::snprintf(at, sizeof at, "(%.3f, %.3f, %.3f)", (*e.held_at_mm)[0], (*e.held_at_mm)[1],
                    (*e.held_at_mm)[2]);
      ending_.note = "the retract was NOT sent: the controller held at " + std::string(at) +
                     ", and " + e.position_doubt +
                     "; it was reset (spindle and coolant off) and sent M5 M9 and the program "
                     "end, and nothing was moved; " +
                     ending_advice();
      return;
    }
    if (e.sent) {
      ending_.state = EndingStatus::State::Sent;
      char held[160] = "";
      if (e.held_at_mm) {
        std::snprintf(held, sizeof held, "held at (%.3f, %.3f, %.3f) %.3f s after the request, ",
                      (*e.held_at_mm)[0], (*e.held_at_mm)[1], (*e.held_at_mm)[2],
                      e.held_t_s - e.request_t_s);
      }
      ending_.note = std::string(held) + "reset, and the ending " +
                     (e.executed ? "executed (the controller reported Idle after it)"
                                 : "queued (no status: its execution is not known)");
      return;
    }
    ending_.state = EndingStatus::State::NotSent;
    ending_.note = "the safe ending could NOT be sent: " +
                   (e.failure.empty() ? (r.failure.empty() ? note : r.failure) : e.failure) + "; " +
                   ending_advice();
    return;
  }
  if (r.completed) {
    ending_.state = EndingStatus::State::Sent;
    ending_.note = (note.empty() ? std::string() : note + "; ") +
                   (live_->line.protocol == comms::Protocol::Ack
                        ? "the controller queued every block of it"
                        : "delivered to the controller; drip feed cannot confirm that it "
                          "executed it");
    return;
  }
  ending_.state = EndingStatus::State::NotSent;
  ending_.note =
      "the safe ending could NOT be sent: " +
      (r.stopped ? (note.empty() ? std::string("the transfer was stopped") : note) : r.failure) +
      "; " + ending_advice();
}

}  // namespace ncd::service
