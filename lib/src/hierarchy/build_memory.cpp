// What a build held in memory needs, known before it reads (model_io.hpp,
// build_memory_estimate): a model past the machine's memory is refused with
// its figures instead of ending in the kernel's out-of-memory kill, which
// says nothing (users' complaint about other converters: "silent exits at
// 1.1 B points"; issue 44).
#include <sys/sysinfo.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>

#include "chunked_build.hpp"
#include "import/pcd_header.hpp"
#include "import/ply_format.hpp"
#include "model_read.hpp"
#include "treecut/las.hpp"
#include "treecut/model_io.hpp"
#include "treecut/pcd.hpp"

namespace treecut {

namespace {

// Points a file declares: a LAS header's count, a PLY's vertex element, a
// PCD's POINTS; a text cloud's lines by its size over the mean length of
// its first data lines. 0 when its header says nothing usable (the reader
// then says what is wrong).
std::uint64_t declared_points(const std::filesystem::path& path) {
  try {
    const std::string head = detail::read_head(path, std::size_t{1} << 16);
    if (looks_like_las(head)) return LasReader(path).info().point_count;
    // A header may declare more than its file holds (the reader says so,
    // exit 2): no more points than 3-byte records fill.
    const std::uint64_t room = std::filesystem::file_size(path) / 3;
    if (head.starts_with("ply")) {
      const ply::Header h = ply::parse_header(head);
      const int v = h.find("vertex");
      return v < 0 ? 0 : std::min(room, h.elements[static_cast<std::size_t>(v)].count);
    }
    if (looks_like_pcd(head)) return std::min(room, pcd::parse_header(head).points);
    std::size_t lines = 0, bytes = 0;
    for (std::size_t at = 0; at < head.size();) {
      const std::size_t end = head.find('\n', at);
      if (end == std::string::npos) break;
      if (end > at && (std::isdigit(static_cast<unsigned char>(head[at])) || head[at] == '-' ||
                       head[at] == '.' || head[at] == '+'))
        ++lines, bytes += end + 1 - at;
      at = end + 1;
    }
    if (lines == 0) return 0;
    return static_cast<std::uint64_t>(double(std::filesystem::file_size(path)) /
                                      (double(bytes) / double(lines)));
  } catch (const std::exception&) {
    return 0;
  }
}

}  // namespace

BuildMemory build_memory_estimate(std::span<const std::filesystem::path> files) {
  BuildMemory m;
  for (const std::filesystem::path& f : files) {
    const std::uint64_t points = declared_points(f);
    m.points += points;
    m.bytes += points * (looks_like_las(detail::read_head(f, 4)) ? kLasBuildBytesPerPoint
                                                                 : kBuildBytesPerPoint);
  }
  return m;
}

std::uint64_t available_memory() {
  std::uint64_t available = 0;
  std::ifstream meminfo("/proc/meminfo");
  std::string key;
  std::uint64_t kib = 0;
  while (meminfo >> key >> kib) {
    if (key == "MemAvailable:") available = kib * 1024;
    meminfo.ignore(64, '\n');
  }
  if (available == 0) {
    struct sysinfo info {};
    if (::sysinfo(&info) == 0) available = std::uint64_t(info.freeram) * info.mem_unit;
  }
  // A container's limit (cgroup v2) binds before the machine's.
  std::ifstream max("/sys/fs/cgroup/memory.max"), current("/sys/fs/cgroup/memory.current");
  std::uint64_t limit = 0, used = 0;
  if ((max >> limit) && (current >> used) && limit > used)
    available = std::min(available, limit - used);
  return available;
}

std::uint64_t detail::resident_bytes() {
  std::ifstream statm("/proc/self/statm");
  std::uint64_t size = 0, resident = 0;
  if (!(statm >> size >> resident)) return 0;
  return resident * static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
}

std::uint64_t default_build_budget() {
  struct sysinfo info {};
  const std::uint64_t total =
      ::sysinfo(&info) == 0 ? std::uint64_t(info.totalram) * info.mem_unit : 0;
  const std::uint64_t available = available_memory();
  return total == 0 ? available : std::min(available, total / 4);
}

std::string build_memory_problem(const std::string& name, const BuildMemory& need,
                                 std::uint64_t budget, bool budget_given) {
  char line[400];
  if (need.points > kMaxBuildPoints) {
    std::snprintf(line, sizeof line,
                  "%s: %llu points; one hierarchy holds at most %llu (its node ids are 32-bit)",
                  name.c_str(), static_cast<unsigned long long>(need.points),
                  static_cast<unsigned long long>(kMaxBuildPoints));
    return line;
  }
  if (budget == 0 || need.bytes <= budget) return {};
  // In GiB, as --memory reads "8G".
  constexpr double kGiB = 1024.0 * 1024.0 * 1024.0;
  std::snprintf(
      line, sizeof line,
      "%s: %llu points need about %.2f GiB to build in memory (%llu bytes a point); "
      "%s %.2f GiB%s",
      name.c_str(), static_cast<unsigned long long>(need.points), double(need.bytes) / kGiB,
      static_cast<unsigned long long>(need.bytes / std::max<std::uint64_t>(need.points, 1)),
      budget_given ? "--memory allows" : "the build may use", double(budget) / kGiB,
      budget_given ? "" : " (a quarter of the memory; --memory SIZE for another budget)");
  return line;
}

}  // namespace treecut
