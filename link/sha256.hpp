// SHA-256 (OpenSSL EVP), incremental, as lowercase hex: the program checksum that the sender
// and the controller compare.
#pragma once

#include <memory>
#include <string>
#include <string_view>

namespace ncd::comms {

class Sha256 {
 public:
  Sha256();
  ~Sha256();
  Sha256(const Sha256&) = delete;
  Sha256& operator=(const Sha256&) = delete;
  void update(std::string_view bytes);
  // Lowercase hex of everything so far; the hash can still be updated afterwards.
  std::string hex() const;

 private:
  struct Ctx;
  std::unique_ptr<Ctx> ctx_;
};

// One-shot SHA-256 of bytes, lowercase hex.
std::string sha256_hex(std::string_view bytes);

}  // namespace ncd::comms
