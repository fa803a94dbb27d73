// The minimum of a sliding window in O(1) amortised per value: the planner's window of limit
// samples takes values at its back (push) and drops them at its front (drop), and asks for the
// smallest value every period (docs/planner.md §4, "The window's smallest axis scales").
//
// A monotone deque: it keeps, in window order, only the values that may still become the
// minimum. A new value removes every kept value at or above it (they leave the window before
// it, so none of them can be the minimum again), so the kept values increase strictly from
// front to back and the front is the minimum. Each
// value is pushed and removed at most once. The minimum is one of the window's values, so it
// is the same number a scan of the window gives, bit for bit.
//
// Storage is a ring sized once (reserve, outside the cycle); push, drop and min neither
// allocate nor throw. Values carry the window's sequence number, so that drop(seq) removes the
// front only if it is that value.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace ncd::motion {

class SlidingMin {
 public:
  // Room for `capacity` values: at least the window's capacity.
  void reserve(std::size_t capacity) { buf_.resize(capacity); }
  void clear() { head_ = size_ = 0; }
  // Value v of the sample with sequence number seq, at the window's back (seq above every
  // sequence number pushed before). Needs size() < capacity, as the window does.
  void push(std::uint64_t seq, double v) {
    while (size_ > 0 && buf_[at(size_ - 1)].v >= v) --size_;
    buf_[at(size_)] = Entry{seq, v};
    ++size_;
  }
  // The window dropped its front sample, sequence number seq.
  void drop(std::uint64_t seq) {
    if (size_ > 0 && buf_[head_].seq == seq) {
      head_ = head_ + 1 < buf_.size() ? head_ + 1 : 0;
      --size_;
    }
  }
  // The smallest value in the window, `none` if it is empty.
  double min_or(double none) const { return size_ > 0 ? buf_[head_].v : none; }
  std::size_t size() const { return size_; }

 private:
  struct Entry {
    std::uint64_t seq;
    double v;
  };
  std::size_t at(std::size_t i) const {
    const std::size_t k = head_ + i;
    return k < buf_.size() ? k : k - buf_.size();
  }
  std::vector<Entry> buf_;
  std::size_t head_ = 0, size_ = 0;
};

}  // namespace ncd::motion
