/**
 * @file atomic_file.cpp
 * @brief All-or-nothing file writes (see atomic_file.hpp).
 */
#include "pedicle_drilling/core/common/atomic_file.hpp"

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <vector>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace pedicle_drilling::core {

AtomicFile::AtomicFile(const std::string& path) : path_(path) {
  const size_t slash = path.find_last_of('/');
  const std::string dir = slash == std::string::npos ? "." : path.substr(0, slash + 1);
  const std::string base = slash == std::string::npos ? path : path.substr(slash + 1);
  if (base.empty() || base == "." || base == "..") {
    throw FileWriteError(path + ": not a file path");
  }
  const std::string tmpl =
      (slash == std::string::npos ? std::string() : dir) + "." + base + ".tmpXXXXXX";
  std::vector<char> buf(tmpl.begin(), tmpl.end());
  buf.push_back('\0');
  fd_ = mkstemp(buf.data());
  if (fd_ < 0) {
    throw FileWriteError(path + ": cannot create a temporary file in '" + dir +
                         "': " + std::strerror(errno));
  }
  tmp_ = buf.data();
}

AtomicFile::~AtomicFile() {
  if (fd_ >= 0) ::close(fd_);
  if (!committed_ && !tmp_.empty()) ::unlink(tmp_.c_str());
}

void AtomicFile::fail(const std::string& what) {
  const int err = errno;
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  ::unlink(tmp_.c_str());
  tmp_.clear();
  throw FileWriteError(path_ + ": " + what + ": " + std::strerror(err));
}

void AtomicFile::write(const std::string& text) {
  if (fd_ < 0 || written_) throw FileWriteError(path_ + ": written twice");
  size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd_, text.data() + done, text.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      fail("write failed");
    }
    done += static_cast<size_t>(n);
  }
  if (::fchmod(fd_, 0644) != 0) fail("chmod failed");
  if (::fsync(fd_) != 0) fail("fsync failed");
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) fail("close failed");
  written_ = true;
}

void AtomicFile::commit() {
  if (!written_ || committed_) throw FileWriteError(path_ + ": nothing written to commit");
  if (std::rename(tmp_.c_str(), path_.c_str()) != 0) fail("rename failed");
  committed_ = true;
}

void writeFileAtomically(const std::string& path, const std::string& text) {
  AtomicFile file(path);
  file.write(text);
  file.commit();
}

}  // namespace pedicle_drilling::core
