// The transfer journal: a small file on disk that says which program is being sent, with which
// settings, and the first block the controller has not confirmed. A restarted `ncd stream`
// reads it and resumes there. The file is one header line (JSON) followed by one fixed-width
// record that is overwritten in place and flushed to disk (fdatasync) as blocks are confirmed,
// so its size does not grow with the program.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

namespace ncd::comms {

struct JournalState {
  std::string program_sha256;  // of the program's blocks, each ended by LF
  std::string settings;        // describe(LineSettings) at the start of the transfer
  std::int64_t blocks = 0;     // blocks in the program
  std::int64_t confirmed = 0;  // blocks the controller has confirmed: resume at this index
  // No block at or after this index has been written to the port: with `confirmed`, the
  // blocks a controller may have run after the sender died (kept ahead of what is written, by a
  // margin, so that it is flushed once per kSentMargin blocks, not once a block).
  std::int64_t sent_bound = 0;
  bool complete = false;  // the whole program was confirmed
};

class TransferJournal {
 public:
  // Creates (or truncates) the journal at path for a new transfer; throws std::runtime_error.
  TransferJournal(const std::string& path, const JournalState& start);
  ~TransferJournal();
  TransferJournal(const TransferJournal&) = delete;
  TransferJournal& operator=(const TransferJournal&) = delete;

  // Records that blocks [0, confirmed) are confirmed; flushes to disk. Never goes backwards.
  void confirm(std::int64_t confirmed);
  // Called before block `index` (0-based) is written: raises sent_bound past it (by
  // kSentMargin, capped at the program's blocks, if known) and flushes, when it is not already.
  void note_writing(std::int64_t index);
  static constexpr std::int64_t kSentMargin = 32;
  // Marks the transfer complete.
  void complete();
  const std::string& path() const { return path_; }

  // Reads a journal; nullopt if there is none. Throws InputError if it is not a journal.
  static std::optional<JournalState> read(const std::string& path);

 private:
  void write_record();
  std::string path_;
  JournalState state_;
  int fd_ = -1;
  long record_offset_ = 0;
};

}  // namespace ncd::comms
