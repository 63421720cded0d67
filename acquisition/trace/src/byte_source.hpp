// Where the reader's bytes come from: a file read with positional reads through one window (traces
// may be many GB, so they are never loaded whole), or a span already in memory (tests, the fuzzer).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace stampscan::trace::detail {

class ByteSource {
 public:
  // Throws std::runtime_error naming the path when the file cannot be opened or sized.
  explicit ByteSource(const std::filesystem::path& path);
  ByteSource(std::span<const std::byte> memory, std::string name);
  ~ByteSource();
  ByteSource(const ByteSource&) = delete;
  ByteSource& operator=(const ByteSource&) = delete;

  std::uint64_t size() const { return size_; }
  const std::string& name() const { return name_; }

  // Up to n bytes from offset: fewer only where the data ends. Valid until the next call. Throws
  // std::runtime_error naming the file on a read error (an I/O failure, not damaged content).
  std::span<const std::byte> view(std::uint64_t offset, std::size_t n);

 private:
  static constexpr std::size_t kWindow = std::size_t{1} << 20;
  int fd_ = -1;
  std::string name_;
  std::uint64_t size_ = 0;
  std::span<const std::byte> memory_;
  std::vector<std::byte> window_;
  std::uint64_t window_offset_ = 0;
  std::size_t window_size_ = 0;
};

}  // namespace stampscan::trace::detail
