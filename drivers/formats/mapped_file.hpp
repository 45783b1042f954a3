// Reading large files without copying them: a regular file mapped read-only (MappedFile), and huge pages for the
// storage of a large vector (prefer_huge_pages). The run-directory readers take gigabyte files in with them.
#pragma once

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string_view>
#include <vector>

namespace noisemon::drivers {

// Asks for huge pages for the storage a vector has reserved: filling a large one then takes a few page faults
// instead of one per 4 KiB (where the kernel offers them only on request; elsewhere this changes nothing).
template <class T>
inline void prefer_huge_pages(const std::vector<T>& v) {
  constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;
  const auto from = (reinterpret_cast<std::uintptr_t>(v.data()) + kHugePage - 1) / kHugePage * kHugePage;
  const auto to = reinterpret_cast<std::uintptr_t>(v.data() + v.capacity()) / kHugePage * kHugePage;
  if (to > from) ::madvise(reinterpret_cast<void*>(from), to - from, MADV_HUGEPAGE);
}

// A regular file mapped read-only (no copy of its bytes); empty when it cannot be mapped, the caller then reads
// it as a stream (whose errors name the problem). release() gives pages already parsed back to the kernel.
class MappedFile {
 public:
  explicit MappedFile(const std::filesystem::path& file) {
    const int fd = ::open(file.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return;
    struct stat st {};
    if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size > 0) {
      void* p = ::mmap(nullptr, static_cast<std::size_t>(st.st_size), PROT_READ, MAP_PRIVATE, fd, 0);
      if (p != MAP_FAILED) {
        data_ = static_cast<const char*>(p);
        size_ = static_cast<std::size_t>(st.st_size);
        ::madvise(p, size_, MADV_SEQUENTIAL);
      }
    }
    ::close(fd);
  }
  ~MappedFile() {
    if (data_) ::munmap(const_cast<char*>(data_), size_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  bool mapped() const { return data_ != nullptr; }
  std::string_view text() const { return {data_, size_}; }
  // Drops the whole pages of [from, to) from this process (they stay in the page cache: reading them again is
  // still correct, only slower).
  void release(const char* from, const char* to) const {
    const auto page = static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE));
    const std::uintptr_t a = (reinterpret_cast<std::uintptr_t>(from) + page - 1) / page * page;
    const std::uintptr_t b = reinterpret_cast<std::uintptr_t>(to) / page * page;
    if (b > a) ::madvise(reinterpret_cast<void*>(a), b - a, MADV_DONTNEED);
  }

 private:
  const char* data_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace noisemon::drivers
