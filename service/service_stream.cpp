// A streamed job's link (the top of service.cpp): start_stream sets up the encoder, the dialect
// check, the journal and the DNC sender on its own thread; follow_stream ends the job once the
// sender is done and the ending resolved; a link that fails while the motion runs ends it in
// error; abort_transfer gives the transfer up.
#include <memory>
#include <mutex>
#include <string>
#include <thread>

#include "core/error.hpp"
#include "core/number_text.hpp"
#include "service/service.hpp"
#include "service/service_live.hpp"

namespace ncd::service {

void Service::abort_transfer(const std::string& why) {
  if (!live_ || live_->done.load(std::memory_order_acquire)) return;
  log("giving the transfer up: " + why);
  if (ending_.state == EndingStatus::State::Pending || ending_.state == EndingStatus::State::None) {
    ending_.note = "given up (" + why + ")";
  }
  if (cycle_ && !cycle_->finished()) cycle_->stop();
  live_->stop = true;
}

std::string Service::link_down_note() const {
  if (!live_) return "";
  const comms::SenderCounts c = live_->sender->counters().load();
  const bool ended = live_->done.load(std::memory_order_acquire);
  const bool lost = c.link_losses > c.reconnects && live_->link_holds.load();
  if (!ended && !lost) return "";
  return "the link to " + live_->line.device + " is " + (ended ? "gone" : "down") +
         ": the safe ending can" + (ended ? "not" : " only") + " be sent" +
         (ended ? "" : " if it comes back within reconnect_max_s") + "; " + ending_advice();
}

void Service::start_stream(const motion::Job& job) {
  const Vec3 start_mm = job.walker().position();
  const LinkSpec& link = *job_.link;
  auto ls = std::make_unique<Live>();
  Live* raw = ls.get();
  ls->line = link.sender.line;
  comms::EncoderSettings enc = link.encoder;
  enc.line = ls->line;
  if (enc.max_block_s <= 0.0) enc.max_block_s = options_.live_max_block_s;
  ls->dialect = link.sender.dialect;
  ls->length_offsets = enc.length_offsets;
  ls->hold_and_reset = ls->line.protocol == comms::Protocol::Ack && link.sender.status_hz > 0.0;
  ls->encoder = std::make_unique<comms::BlockEncoder>(enc, [raw](const comms::EncodedBlock& b) {
    if (raw->gate_closed && !raw->writing_ending) return;
    if (raw->dialect) {
      if (const auto v = comms::check_line(*raw->dialect, b.text, raw->dialect_state)) {
        const std::string why = "block '" + b.text + "' refused before it was queued: " +
                                comms::describe(*v, *raw->dialect);
        if (raw->writing_ending) {
          raw->ending_refused = why;  // the rest of the ending still goes
        } else {
          raw->refused = why;
          raw->gate_closed = true;
        }
        return;
      }
    }
    ++raw->blocks_encoded;
    raw->chars_encoded += b.chars;
    raw->trace.add(b.number, b.start_s_mm, b.end_s_mm, b.start_t_s, b.end_t_s, b.chars);
    if (b.closed_by != comms::BlockClose::Words && b.closed_by != comms::BlockClose::Comment) {
      raw->queued_at = b.end;
    }
    if (raw->writing_ending) raw->ending_blocks.push_back(b.text);
    raw->blocks.push(b.text);
  });
  motion::Setpoint start;
  start.p = start_mm;
  if (job_.program) {
    // The program's blocks, as `ncd replay --blocks` writes them: the header, the preamble and
    // the events and rapids before the first planned move, then the start of the path.
    ls->program = std::make_unique<comms::ProgramBlocks>(*job_.program, *ls->encoder,
                                                         job.segment_starts_mm());
    ls->program->begin(job_.header);
    ls->program->push(start);
  } else {
    // A restart: the preamble's G43 H is the controller's; the path's coordinates hold ncd's.
    if (job_.restart && enc.length_offsets) {
      ls->encoder->set_offset(job_.restart->length_offset_mm);
    }
    ls->encoder->push(start);
  }
  if (!link.journal.empty()) {
    comms::JournalState js;
    js.program_sha256 = "live job " + job_.name;
    js.settings = comms::describe(ls->line);
    ls->journal = std::make_unique<comms::TransferJournal>(link.journal, js);
  }
  comms::SenderSettings ss = link.sender;
  if (job_.restart) ss.preamble = job_.restart->preamble;
  ls->sender =
      std::make_unique<comms::DncSender>(ss, ls->blocks, [raw](const comms::SenderEvent& e) {
        std::lock_guard lock(raw->mutex);
        raw->last_event = e.text;
        if (e.kind != comms::SenderEvent::Kind::Progress) raw->events.push_back(e.text);
      });
  ls->sender->set_journal(ls->journal.get());
  ls->sender->on_hold([raw](bool hold) {
    raw->link_holds.store(hold);
    raw->hold_request.store(hold ? 1 : 0);
  });
  // No exception may leave the thread: one becomes the report's failure, the job's error.
  ls->thread = std::thread([raw] {
    try {
      raw->report = raw->sender->run(raw->stop);
    } catch (const std::exception& e) {
      raw->report.completed = false;
      raw->report.failure = std::string("the sender failed: ") + e.what();
    } catch (...) {
      raw->report.completed = false;
      raw->report.failure = "the sender failed (unknown exception)";
    }
    raw->done.store(true, std::memory_order_release);
  });
  log("streaming job " + job_.name + " to " + ls->line.device + " at " + comms::describe(ls->line));
  live_ = std::move(ls);
}

void Service::follow_stream() {
  if (!live_->done.load(std::memory_order_acquire)) return;
  live_->thread.join();
  {
    std::vector<std::string> events;
    {
      std::lock_guard lock(live_->mutex);
      events.swap(live_->events);
    }
    for (const std::string& e : events) emit(EventKind::Link, e);
  }
  const comms::SenderReport& r = live_->report;
  State s = final_state_;
  std::string why = s == State::Done ? "the motion ended and the controller has every block"
                                     : (s == State::Error ? error_ : stop_why_);
  const bool ending = ending_.state == EndingStatus::State::Pending;
  if (ending) resolve_ending(r);
  const bool ok = ending ? ending_.state != EndingStatus::State::NotSent : r.completed;
  if (!ok && !ending) {  // a job that reached its end: its own end may not have arrived
    ending_.state = EndingStatus::State::NotSent;
    ending_.note =
        "the program's own end (retract, M5, M2) may not have reached the "
        "controller; " +
        ending_advice();
  }
  const std::string failure = r.stopped ? std::string("given up") : r.failure;
  if (!ok && s != State::Error) {
    s = State::Error;
    error_ = "the transfer to " + live_->line.device + " did not complete: " + failure + "; " +
             ending_.note;
    why = error_;
  } else if (!ok) {
    error_ += "; the transfer to " + live_->line.device + " did not complete: " + failure + "; " +
              ending_.note;
    why = error_;
  }
  log("sent " + std::to_string(r.blocks) + " blocks (" + std::to_string(r.bytes_written) +
      " bytes) to " + live_->line.device + " in " + text::sig(r.duration_s) + " s, " +
      text::sig(100.0 * r.link_use) + " % of the line; sha256 " + r.program_sha256);
  if (!ok || (s == State::Error && !alarmed_)) emit(EventKind::Alarm, error_);
  log("ending: " + std::string(to_string(ending_.state)) +
      (ending_.note.empty() ? std::string() : " (" + ending_.note + ")"));
  set_state(s, HoldHolder::None, why);
  end_job();
}

// The sender ended while the motion ran: nothing more reaches the controller.
void Service::link_failed() {
  live_->thread.join();
  const comms::SenderReport& r = live_->report;
  const std::string failure =
      r.failure.empty() ? (r.stopped ? std::string("stopped") : std::string("ended")) : r.failure;
  ending_.state = EndingStatus::State::NotSent;
  ending_.note =
      "the safe ending (retract, M5, M9, program end) could NOT be sent: the link is "
      "gone; " +
      ending_advice();
  error_ = "the link to " + live_->line.device + " failed while the job ran: " + failure + "; " +
           ending_.note;
  log("job " + job_.name + " failed: " + error_);
  cycle_.reset();  // nothing it walks reaches the machine any more
  live_->blocks.close();
  job_.sink.reset();
  emit(EventKind::Alarm, error_);
  set_state(State::Error, HoldHolder::None, error_);
  end_job();
}

}  // namespace ncd::service
