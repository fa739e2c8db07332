#include "treecut/registry.hpp"

#include <dlfcn.h>
#include <elf.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/plugin.hpp"

namespace treecut {

const StrategyRegistry::Entry* StrategyRegistry::find(std::string_view name) const {
  for (const Entry& e : entries_) {
    if (e.info.name == name) return &e;
  }
  return nullptr;
}

void StrategyRegistry::add(std::string name, std::string description, StrategyFactory factory) {
  if (name.empty() || !factory) throw std::invalid_argument("strategy: empty name or factory");
  if (find(name) != nullptr) {
    throw std::invalid_argument("strategy '" + name + "' is already registered");
  }
  const std::unique_ptr<Strategy> probe = factory();
  if (!probe || probe->name() != name) {
    throw std::invalid_argument("strategy '" + name + "': the factory makes another strategy");
  }
  entries_.push_back(
      {StrategyInfo{std::move(name), std::move(description), probe->param_specs(), origin_},
       std::move(factory)});
}

bool StrategyRegistry::contains(std::string_view name) const {
  return find(name) != nullptr;
}

std::unique_ptr<Strategy> StrategyRegistry::create(std::string_view name) const {
  if (const Entry* e = find(name)) {
    std::unique_ptr<Strategy> s = e->factory();
    if (!s)
      throw std::runtime_error("strategy '" + e->info.name + "' (" + e->info.origin +
                               "): the factory returned no strategy");
    s->set_origin(e->info.origin);
    return s;
  }
  std::string known;
  for (const std::string& n : names()) known += (known.empty() ? "" : ", ") + n;
  throw InputError("unknown strategy '" + std::string(name) + "' (known: " + known + ")");
}

std::vector<StrategyInfo> StrategyRegistry::list() const {
  std::vector<StrategyInfo> out;
  out.reserve(entries_.size());
  for (const Entry& e : entries_) out.push_back(e.info);
  std::sort(out.begin(), out.end(),
            [](const StrategyInfo& a, const StrategyInfo& b) { return a.name < b.name; });
  return out;
}

std::vector<std::string> StrategyRegistry::names() const {
  std::vector<std::string> out;
  for (const Entry& e : entries_) out.push_back(e.info.name);
  std::sort(out.begin(), out.end());
  return out;
}

namespace {

// What an ELF header says, read without mapping anything (dlopen would map
// a truncated library's segments past its end and die of SIGBUS inside it).
struct ElfFacts {
  unsigned char elf_class = 0, data = 0;
  std::uint16_t type = 0, machine = 0;
  std::string problem;  // empty when complete as far as the headers tell
};

template <class Ehdr, class Phdr>
void read_elf_tables(int fd, std::uint64_t size, ElfFacts& facts) {
  Ehdr eh{};
  if (::pread(fd, &eh, sizeof eh, 0) != static_cast<ssize_t>(sizeof eh)) {
    facts.problem = "truncated (shorter than an ELF header)";
    return;
  }
  facts.type = eh.e_type;
  facts.machine = eh.e_machine;
  const auto past_end = [&](std::uint64_t offset, std::uint64_t bytes) {
    return offset > size || bytes > size - offset;
  };
  if (eh.e_phentsize != sizeof(Phdr) ||
      past_end(eh.e_phoff, std::uint64_t{eh.e_phnum} * sizeof(Phdr))) {
    facts.problem = "truncated or damaged (its program headers are not inside the file)";
    return;
  }
  if (eh.e_shoff != 0 && past_end(eh.e_shoff, std::uint64_t{eh.e_shnum} * eh.e_shentsize)) {
    facts.problem = "truncated (its section headers end past the end of the file)";
    return;
  }
  for (unsigned i = 0; i < eh.e_phnum; ++i) {
    Phdr ph{};
    if (::pread(fd, &ph, sizeof ph, static_cast<off_t>(eh.e_phoff + i * sizeof ph)) !=
        static_cast<ssize_t>(sizeof ph)) {
      facts.problem = "truncated (a program header cannot be read)";
      return;
    }
    if (ph.p_type == PT_LOAD && past_end(ph.p_offset, ph.p_filesz)) {
      facts.problem = "truncated (a loadable segment ends past the end of the file)";
      return;
    }
  }
}

// Reads the ELF identity of the regular file open as FD (SIZE bytes).
ElfFacts elf_facts(int fd, std::uint64_t size) {
  ElfFacts facts;
  unsigned char ident[EI_NIDENT] = {};
  if (::pread(fd, ident, sizeof ident, 0) != static_cast<ssize_t>(sizeof ident) ||
      std::memcmp(ident, ELFMAG, SELFMAG) != 0) {
    facts.problem = "not a shared library (no ELF header)";
    return facts;
  }
  facts.elf_class = ident[EI_CLASS];
  facts.data = ident[EI_DATA];
  if (facts.elf_class == ELFCLASS64)
    read_elf_tables<Elf64_Ehdr, Elf64_Phdr>(fd, size, facts);
  else if (facts.elf_class == ELFCLASS32)
    read_elf_tables<Elf32_Ehdr, Elf32_Phdr>(fd, size, facts);
  else
    facts.problem = "not a shared library (an unknown ELF class)";
  return facts;
}

// This program's own ELF identity: a plugin must match it.
const ElfFacts& own_elf() {
  static const ElfFacts facts = [] {
    ElfFacts f;
    const int fd = ::open("/proc/self/exe", O_RDONLY | O_CLOEXEC);
    if (fd < 0) return f;
    struct stat st {};
    if (::fstat(fd, &st) == 0) f = elf_facts(fd, static_cast<std::uint64_t>(st.st_size));
    ::close(fd);
    return f;
  }();
  return facts;
}

// A plugin path is a path like every other input: an existing regular file,
// an ELF shared object for this machine whose headers and loadable segments
// lie inside it. Returns its absolute path for dlopen (which would otherwise
// search the library path for a bare name, and run the constructors of a
// system library of that name before saying it is no plugin).
std::filesystem::path checked_plugin_path(const std::filesystem::path& path) {
  const std::string shown = quoted_name(path);
  const int fd = open_regular_file(path);  // InputError: missing, a FIFO, a directory...
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int error = errno;
    ::close(fd);
    throw InputError(system_error_text(path, error));
  }
  const ElfFacts facts = elf_facts(fd, static_cast<std::uint64_t>(st.st_size));
  ::close(fd);
  if (!facts.problem.empty()) throw InputError(shown + ": " + facts.problem);
  const ElfFacts& own = own_elf();
  if (own.elf_class != 0 &&
      (facts.elf_class != own.elf_class || facts.data != own.data || facts.machine != own.machine))
    throw InputError(shown + ": an ELF file for another kind of machine (class " +
                     std::to_string(facts.elf_class) + ", machine " +
                     std::to_string(facts.machine) + "; this program is class " +
                     std::to_string(own.elf_class) + ", machine " + std::to_string(own.machine) +
                     ")");
  if (facts.type != ET_DYN)
    throw InputError(shown + ": an ELF " +
                     (facts.type == ET_EXEC  ? std::string("executable")
                      : facts.type == ET_REL ? std::string("object file (.o)")
                                             : "file of type " + std::to_string(facts.type)) +
                     ", not a shared library");
  std::error_code ec;
  const std::filesystem::path absolute = std::filesystem::absolute(path, ec);
  return ec ? path : absolute;
}

// What the trial in the child reported: its error message, empty when it
// loaded and registered. Throws, naming WHERE, when the child ended without
// a report (it crashed, or the library's code ended it).
std::string read_trial(int fd, pid_t child, const std::string& where) {
  std::string report;
  char buffer[512];
  for (;;) {
    const ssize_t n = ::read(fd, buffer, sizeof buffer);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    report.append(buffer, static_cast<std::size_t>(n));
  }
  ::close(fd);
  int status = 0;
  while (::waitpid(child, &status, 0) < 0 && errno == EINTR) {
  }
  if (report.empty()) {
    const std::string how =
        WIFSIGNALED(status)
            ? std::string("crashed a test process (") + ::strsignal(WTERMSIG(status)) + ")"
            : "ended a test process (exit status " + std::to_string(WEXITSTATUS(status)) + ")";
    throw InputError(where + ": cannot load plugin: loading it " + how +
                     "; the library is damaged or not meant to be loaded");
  }
  return report.substr(1);  // after the 'K' or 'E' that makes it non-empty
}

}  // namespace

// dlopen runs the library's code in this process (relocations, its
// constructors), and the entry points are called as functions: a library
// damaged inside (a bad pointer in its dynamic section), one whose
// constructor exits, or one whose version "function" is a variable would
// crash or end the host. The whole load and registration is first tried in a
// child process, whose output goes nowhere, on a copy of the registry; only
// a library that passes is loaded here, so one that is no plugin never runs
// its constructors in the host. (Plugins are loaded at start-up, before the
// program starts threads.)
void StrategyRegistry::try_plugin_in_child(const std::filesystem::path& path,
                                           const std::filesystem::path& open_as) const {
  const std::string where = quoted_name(path);
  int pipe_fds[2];
  if (::pipe2(pipe_fds, O_CLOEXEC) != 0) return;  // no trial; the real load decides
  const pid_t child = ::fork();
  if (child < 0) {
    ::close(pipe_fds[0]);
    ::close(pipe_fds[1]);
    return;
  }
  if (child == 0) {
    ::close(pipe_fds[0]);
    const int null = ::open("/dev/null", O_WRONLY | O_CLOEXEC);
    if (null >= 0) {
      ::dup2(null, STDOUT_FILENO);
      ::dup2(null, STDERR_FILENO);
    }
    std::string report = "K";
    try {
      StrategyRegistry trial = *this;
      trial.load_and_register(path, open_as);
    } catch (const std::exception& e) {
      report = std::string("E") + e.what();
    }
    (void)!::write(pipe_fds[1], report.data(), report.size());
    ::_exit(0);
  }
  ::close(pipe_fds[1]);
  if (const std::string error = read_trial(pipe_fds[0], child, where); !error.empty())
    throw InputError(error);
}

void StrategyRegistry::load_and_register(const std::filesystem::path& path,
                                         const std::filesystem::path& open_as) {
  const std::string where = quoted_name(path);
  // RTLD_LOCAL: two plugins may define the same internal symbols. The handle is
  // never closed (see the header), so it is deliberately not kept.
  void* handle = dlopen(open_as.c_str(), RTLD_NOW | RTLD_LOCAL);
  if (handle == nullptr) {
    const char* why = dlerror();
    throw InputError(where + ": cannot load plugin: " + (why != nullptr ? why : "unknown error"));
  }
  using VersionFn = std::uint32_t (*)();
  using RegisterFn = void (*)(StrategyRegistry&);
  auto* version = reinterpret_cast<VersionFn>(dlsym(handle, kPluginVersionSymbol));
  auto* entry = reinterpret_cast<RegisterFn>(dlsym(handle, kPluginRegisterSymbol));
  if (version == nullptr || entry == nullptr) {
    dlclose(handle);  // nothing from it was used yet
    throw InputError(where + ": not a treecut plugin (no " + kPluginVersionSymbol + "/" +
                     kPluginRegisterSymbol + ")");
  }
  if (const std::uint32_t v = version(); v != kPluginApiVersion) {
    dlclose(handle);
    throw InputError(where + ": plugin API version " + std::to_string(v) + ", this treecut has " +
                     std::to_string(kPluginApiVersion));
  }
  const std::size_t before = entries_.size();
  origin_ = path.string();
  try {
    entry(*this);
  } catch (const std::exception& e) {
    entries_.resize(before);  // all or nothing
    origin_ = "built-in";
    throw InputError(where + ": plugin registration failed: " + e.what());
  } catch (...) {
    entries_.resize(before);
    origin_ = "built-in";
    throw InputError(where + ": plugin registration failed");
  }
  origin_ = "built-in";
}

void StrategyRegistry::load_plugin(const std::filesystem::path& path) {
  const std::filesystem::path open_as = checked_plugin_path(path);
  try_plugin_in_child(path, open_as);
  load_and_register(path, open_as);
}

}  // namespace treecut
