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

namespace noisemon::drivers::formats {

// Asks for huge pages for the storage a vector has reserved: filling a large one then takes a few page faults
// instead of one per 4 KiB (where the kernel offers them only on request; elsewhere this changes nothing).
// The whole pages of size `page` inside [first, last), as advice to the kernel (addresses stay pointers: the
// alignment is an offset from `first`).
inline void advise_pages(char* first, char* last, std::uintptr_t page, int advice) {
  const auto a = reinterpret_cast<std::uintptr_t>(first), b = reinterpret_cast<std::uintptr_t>(last);
  const std::uintptr_t from = (a + page - 1) / page * page, to = b / page * page;
  if (to > from) ::madvise(first + (from - a), to - from, advice);
}

template <class T>
inline void prefer_huge_pages(const std::vector<T>& v) {
  auto* first = reinterpret_cast<char*>(const_cast<T*>(v.data()));
  advise_pages(first, first + v.capacity() * sizeof(T), std::uintptr_t{2} << 20, MADV_HUGEPAGE);
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
    advise_pages(const_cast<char*>(from), const_cast<char*>(to), static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE)),
                 MADV_DONTNEED);
  }

 private:
  const char* data_ = nullptr;
  std::size_t size_ = 0;
};

}  // namespace noisemon::drivers::formats
