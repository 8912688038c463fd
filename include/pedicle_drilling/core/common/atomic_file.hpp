/**
 * @file atomic_file.hpp
 * @brief Files written all or nothing: the text goes to a unique temporary file (mkstemp) in the
 *        destination's directory, is flushed and fsync'ed, and is renamed over the destination
 *        only on commit() (atomic on POSIX within one file system). A reader sees the old file
 *        or the new one, never a part; an uncommitted file leaves nothing behind.
 */
#pragma once

#include <stdexcept>
#include <string>

namespace pedicle_drilling::core {

/** @brief A file that cannot be written; the message names the path and the reason. */
class FileWriteError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/**
 * @brief One output file, prepared then committed. Creating several AtomicFiles before
 *        committing any checks every destination first, so a tool that writes several outputs
 *        either writes them all or none (the temporary files are removed on failure).
 */
class AtomicFile {
 public:
  /** @brief Creates the temporary file beside `path`. @throws FileWriteError. */
  explicit AtomicFile(const std::string& path);
  /** @brief Removes the temporary file unless committed. */
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  /** @brief Writes the whole content, fsyncs and closes the temporary. @throws FileWriteError. */
  void write(const std::string& text);
  /** @brief Renames the written temporary over the destination. @throws FileWriteError. */
  void commit();

  /** @brief The destination path. */
  const std::string& path() const { return path_; }

 private:
  [[noreturn]] void fail(const std::string& what);

  std::string path_;
  std::string tmp_;
  int fd_ = -1;
  bool written_ = false;
  bool committed_ = false;
};

/** @brief AtomicFile in one call: `text` to `path`, all or nothing. @throws FileWriteError. */
void writeFileAtomically(const std::string& path, const std::string& text);

}  // namespace pedicle_drilling::core
