// Transfer journal: header line, then `confirmed NNNNNNNNNNNN sent NNNNNNNNNNNN complete N\n` at
// a fixed offset (journals written before `sent` was added have `confirmed … complete N`).
#include "link/transfer_journal.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "core/error.hpp"
#include "core/input_file.hpp"
#include "core/json_input.hpp"

namespace ncd::comms {
namespace {

constexpr const char* kMagic = "ncd-transfer-journal-1";

std::string record_text(std::int64_t confirmed, std::int64_t sent_bound, bool complete) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "confirmed %012lld sent %012lld complete %d\n",
                static_cast<long long>(confirmed), static_cast<long long>(sent_bound),
                complete ? 1 : 0);
  return buf;
}

}  // namespace

// The journal is made whole beside its path (header and first record, synced) and renamed
// over it: a reader, or a resume after the sender was killed at any instant, finds the old
// journal or the new one, never a truncated one. The descriptor stays on the renamed file.
TransferJournal::TransferJournal(const std::string& path, const JournalState& start)
    : path_(path), state_(start) {
  const std::string temp = path + ".tmp" + std::to_string(::getpid());
  fd_ = ::open(temp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) {
    throw std::runtime_error("cannot create the transfer journal " + path + " (as " + temp +
                             "): " + std::strerror(errno));
  }
  const nlohmann::json header{{"journal", kMagic},
                              {"program_sha256", start.program_sha256},
                              {"settings", start.settings},
                              {"blocks", start.blocks}};
  const std::string head = header.dump() + "\n";
  record_offset_ = static_cast<long>(head.size());
  const std::string first =
      head + record_text(state_.confirmed, state_.sent_bound, state_.complete);
  if (::write(fd_, first.data(), first.size()) != static_cast<ssize_t>(first.size()) ||
      ::fdatasync(fd_) != 0 || ::rename(temp.c_str(), path.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    ::close(fd_);
    fd_ = -1;
    ::unlink(temp.c_str());
    throw std::runtime_error("cannot write the transfer journal " + path + ": " + why);
  }
}

TransferJournal::~TransferJournal() {
  if (fd_ >= 0) ::close(fd_);
}

void TransferJournal::confirm(std::int64_t confirmed) {
  if (confirmed <= state_.confirmed) return;
  state_.confirmed = confirmed;
  write_record();
}

void TransferJournal::note_writing(std::int64_t index) {
  if (index < state_.sent_bound) return;
  state_.sent_bound = index + kSentMargin;
  if (state_.blocks > 0) state_.sent_bound = std::min(state_.sent_bound, state_.blocks);
  state_.sent_bound = std::max(state_.sent_bound, index + 1);
  write_record();
}

void TransferJournal::complete() {
  state_.complete = true;
  state_.confirmed = state_.blocks;
  write_record();
}

void TransferJournal::write_record() {
  const std::string rec = record_text(state_.confirmed, state_.sent_bound, state_.complete);
  if (::pwrite(fd_, rec.data(), rec.size(), record_offset_) != static_cast<ssize_t>(rec.size()) ||
      ::fdatasync(fd_) != 0) {
    throw std::runtime_error("cannot update the transfer journal " + path_ + ": " +
                             std::strerror(errno));
  }
}

std::optional<JournalState> TransferJournal::read(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return std::nullopt;  // no journal yet
  require_regular_file(path, "transfer journal");           // never open a FIFO or a device
  std::ifstream in(path);
  if (!in) return std::nullopt;
  const auto bad = [&](const std::string& why) {
    return InputError("the transfer journal " + path + " is not usable (" + why +
                      "): remove it, or pass --restart to send the program from the start");
  };
  std::string head, rec;
  if (!std::getline(in, head) || !std::getline(in, rec)) throw bad("truncated");
  JournalState s;
  try {
    const auto j = parse_json_input(head, path);
    if (j.at("journal").get<std::string>() != kMagic) throw bad("unknown format");
    s.program_sha256 = j.at("program_sha256").get<std::string>();
    s.settings = j.at("settings").get<std::string>();
    s.blocks = json_integer(j.at("blocks"), 0, std::numeric_limits<std::int64_t>::max(), "blocks");
  } catch (const nlohmann::json::exception& e) {
    throw bad(e.what());
  } catch (const InputError& e) {
    if (std::string(e.what()).rfind("the transfer journal", 0) == 0) throw;  // already bad()
    throw bad(e.what());
  }
  long long confirmed = -1, sent = -1;
  int complete = -1;
  if (std::sscanf(rec.c_str(), "confirmed %lld sent %lld complete %d", &confirmed, &sent,
                  &complete) != 3) {
    sent = s.blocks;  // an older journal: every block may have been written
    if (std::sscanf(rec.c_str(), "confirmed %lld complete %d", &confirmed, &complete) != 2) {
      throw bad("bad record '" + rec + "'");
    }
  }
  if (confirmed < 0 || confirmed > s.blocks || sent < 0 || sent > s.blocks ||
      (complete != 0 && complete != 1)) {
    throw bad("bad record '" + rec + "'");
  }
  s.confirmed = confirmed;
  s.sent_bound = std::max(sent, confirmed);
  s.complete = complete == 1;
  return s;
}

}  // namespace ncd::comms
