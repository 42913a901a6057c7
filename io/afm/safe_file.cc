#include "io/afm/safe_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace cellflow::afm {
namespace {

const char* file_type_name(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISSOCK(mode)) return "a socket";
  return "not a regular file";
}

Status not_regular(const std::string& path, mode_t mode) {
  return invalid_argument(path + ": refusing to read " + file_type_name(mode) + "; need a regular file");
}

// Closes the descriptor on every return path.
struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

StatusOr<std::string> read_regular_file(const std::string& path, std::uint64_t max_bytes) {
  struct stat st {};
  // stat() first so that a FIFO is never opened (opening one can block).
  if (::stat(path.c_str(), &st) != 0) {
    return Status(StatusCode::kNotFound, path + ": " + std::strerror(errno));
  }
  if (!S_ISREG(st.st_mode)) return not_regular(path, st.st_mode);

  // O_NONBLOCK: should the path be swapped for a FIFO between stat and open, the
  // open still returns at once and fstat below refuses it.
  Fd f;
  f.fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (f.fd < 0) return Status(StatusCode::kNotFound, path + ": " + std::strerror(errno));
  if (::fstat(f.fd, &st) != 0) return invalid_argument(path + ": fstat: " + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) return not_regular(path, st.st_mode);
  if (static_cast<std::uint64_t>(st.st_size) > max_bytes) {
    return Status(StatusCode::kResourceExhausted, path + ": " + std::to_string(st.st_size) +
                                                      " bytes exceeds the limit of " +
                                                      std::to_string(max_bytes) + " bytes");
  }
  if (st.st_size == 0) return invalid_argument(path + ": file is empty");

  std::string bytes(static_cast<std::size_t>(st.st_size), '\0');
  std::size_t done = 0;
  while (done < bytes.size()) {
    ssize_t n = ::read(f.fd, bytes.data() + done, bytes.size() - done);
    if (n < 0) {
      if (errno == EINTR) continue;
      return invalid_argument(path + ": read error: " + std::strerror(errno));
    }
    if (n == 0) break;  // shrank while reading
    done += static_cast<std::size_t>(n);
  }
  if (done != bytes.size()) {
    return invalid_argument(path + ": file shrank while reading (" + std::to_string(done) + " of " +
                            std::to_string(bytes.size()) + " bytes)");
  }
  return bytes;
}

}  // namespace cellflow::afm
