// The state of a streamed job that service.cpp, service_stream.cpp and service_ending.cpp share:
// the encoder, the live block queue, the sender and its thread, the owner's dialect check, and
// the ending's progress (the top of service.cpp says which thread touches what).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "gcode/dialect/dialect.hpp"
#include "link/live_blocks.hpp"
#include "link/program_blocks.hpp"
#include "link/transfer_journal.hpp"
#include "service/commanded_state.hpp"
#include "service/service.hpp"

namespace ncd::service {

// The encoder, the queue and the sender thread of a streamed job.
struct Service::Live {
  comms::LiveBlocks blocks;
  std::unique_ptr<comms::BlockEncoder> encoder;
  std::unique_ptr<comms::ProgramBlocks>
      program;  // the job's events around the encoder; may be null
  std::unique_ptr<comms::TransferJournal> journal;
  std::unique_ptr<comms::DncSender> sender;
  std::thread thread;
  std::atomic<bool> stop{false};
  std::atomic<bool> done{false};
  std::atomic<int> hold_request{-1};    // the sender's last hold (1) or release (0); -1: none new
  std::atomic<bool> link_holds{false};  // the sender's last hold state
  std::int64_t blocks_encoded = 0, chars_encoded = 0;  // owner's thread
  BlockTrace trace;             // owner's thread: every block queued, in order
  bool length_offsets = false;  // the blocks leave the tool length out (the controller's G43 H)
  // The owner's check of each block against the controller's dialect before it is queued
  // (the sender's own check, on the same blocks in the same order, gives the same verdict).
  std::optional<comms::Dialect> dialect;
  comms::DialectState dialect_state;
  std::string refused;            // the first block refused, and why; empty: none
  bool gate_closed = false;       // after a refusal: nothing more is queued until the ending
  std::optional<Vec3> queued_at;  // where the blocks queued so far leave the tool
  bool writing_ending = false;    // the ending's blocks are being queued
  bool ending_written = false;
  std::vector<std::string> ending_blocks;  // as queued
  std::string ending_refused;              // an ending block the dialect refused (left out)
  bool hold_and_reset = false;             // the ending goes by DncSender::end_with
  comms::SenderReport report;              // written by the thread before done
  comms::LineSettings line;
  mutable std::mutex mutex;
  std::string last_event;           // guarded by mutex
  std::vector<std::string> events;  // guarded by mutex: not yet passed to the observers
  ~Live() {
    stop = true;
    if (thread.joinable()) thread.join();
  }
};

}  // namespace ncd::service
