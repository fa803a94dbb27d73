// Blocks handed from the service's I/O thread (the block encoder, fed live from the cycle's
// setpoints) to the sender's thread. A short mutex-guarded queue: neither side is the cycle
// thread, and the sender polls it every few milliseconds.
#pragma once

#include <deque>
#include <mutex>
#include <string>

#include "link/dnc_sender.hpp"

namespace ncd::comms {

class LiveBlocks : public BlockSource {
 public:
  // Producer: one more block (text without end of block).
  void push(std::string text) {
    std::lock_guard lock(mutex_);
    queue_.push_back(std::move(text));
  }
  // Producer: no more blocks.
  void close() {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  // Blocks waiting for the sender.
  std::size_t waiting() const {
    std::lock_guard lock(mutex_);
    return queue_.size();
  }
  BlockStatus next(std::string& text) override {
    std::lock_guard lock(mutex_);
    if (queue_.empty()) return closed_ ? BlockStatus::End : BlockStatus::NotYet;
    text = std::move(queue_.front());
    queue_.pop_front();
    return BlockStatus::Ready;
  }

 private:
  mutable std::mutex mutex_;
  std::deque<std::string> queue_;
  bool closed_ = false;
};

}  // namespace ncd::comms
