#include "byte_source.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace stampscan::trace::detail {

ByteSource::ByteSource(const std::filesystem::path& path) : name_(path.string()) {
  // O_NONBLOCK: opening a FIFO for reading would otherwise wait for a writer, forever.
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd_ < 0) throw std::runtime_error(name_ + ": cannot open: " + std::strerror(errno));
  struct stat st {};
  if (::fstat(fd_, &st) != 0 || !S_ISREG(st.st_mode)) {
    const std::string why = S_ISDIR(st.st_mode)    ? "is a folder, not a file"
                            : S_ISFIFO(st.st_mode) ? "is a FIFO, not a regular file"
                            : S_ISCHR(st.st_mode) || S_ISBLK(st.st_mode) ? "is a device, not a regular file"
                            : S_ISSOCK(st.st_mode) ? "is a socket, not a regular file"
                                                   : std::strerror(errno);
    ::close(fd_);
    fd_ = -1;
    throw std::runtime_error(name_ + ": cannot read: " + why);
  }
  size_ = static_cast<std::uint64_t>(st.st_size);
}

ByteSource::ByteSource(std::span<const std::byte> memory, std::string name)
    : name_(std::move(name)), size_(memory.size()), memory_(memory) {}

ByteSource::~ByteSource() {
  if (fd_ >= 0) ::close(fd_);
}

std::span<const std::byte> ByteSource::view(std::uint64_t offset, std::size_t n) {
  if (offset >= size_) return {};
  n = static_cast<std::size_t>(std::min<std::uint64_t>(n, size_ - offset));
  if (fd_ < 0) return memory_.subspan(static_cast<std::size_t>(offset), n);
  if (offset >= window_offset_ && offset + n <= window_offset_ + window_size_)
    return std::span<const std::byte>(window_).subspan(static_cast<std::size_t>(offset - window_offset_), n);
  // Refill from offset: at least a whole window, so that the small reads of a sequential scan are
  // served from memory; larger when one record needs more.
  const std::size_t want = static_cast<std::size_t>(std::min<std::uint64_t>(std::max(n, kWindow), size_ - offset));
  if (window_.size() < want) window_.resize(want);
  // Give back the memory of one huge record once the scan is past it.
  if (window_.size() > 8 * kWindow && want <= kWindow) window_ = std::vector<std::byte>(want);
  std::size_t got = 0;
  while (got < want) {
    const ssize_t r = ::pread(fd_, window_.data() + got, want - got, static_cast<off_t>(offset + got));
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) throw std::runtime_error(name_ + ": read failed at byte " + std::to_string(offset + got) + ": " +
                                        std::strerror(errno));
    if (r == 0) break;  // the file shrank while we read it: serve what is there
    got += static_cast<std::size_t>(r);
  }
  window_offset_ = offset;
  window_size_ = got;
  return std::span<const std::byte>(window_).subspan(0, std::min(n, got));
}

}  // namespace stampscan::trace::detail
