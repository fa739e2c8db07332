#include "option_checks.hpp"

#include <charconv>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string>
#include <string_view>

#include "treecut/cache_folder.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut::cli {

namespace {

std::string shown(std::string_view token) {
  return "'" + printable_excerpt(token) + "'";
}

std::string number_text(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%g", v);
  return text;
}

}  // namespace

CLI::Validator whole_number(std::uint64_t lo, std::uint64_t hi) {
  const std::string range =
      " (a whole number from " + std::to_string(lo) + " to " + std::to_string(hi) + ")";
  return CLI::Validator(
      [lo, hi, range](std::string& text) -> std::string {
        std::string_view digits = text;
        if (digits.starts_with('+')) digits.remove_prefix(1);
        const bool negative = digits.starts_with('-');
        if (negative) digits.remove_prefix(1);
        std::uint64_t v = 0;
        const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
        const bool whole = !digits.empty() && end == digits.data() + digits.size() &&
                           (ec == std::errc() || ec == std::errc::result_out_of_range);
        if (!whole) return shown(text) + " is not a whole number" + range;
        if (ec == std::errc::result_out_of_range || (negative && v != 0) || v < lo || v > hi)
          return shown(text) + " is out of range" + range;
        return {};
      },
      "INT in [" + std::to_string(lo) + " - " + std::to_string(hi) + "]", "WHOLE");
}

CLI::Validator finite_number(double lo, double hi) {
  const std::string range = " (a number from " + number_text(lo) + " to " + number_text(hi) + ")";
  return CLI::Validator(
      [lo, hi, range](std::string& text) -> std::string {
        std::string_view token = text;
        if (token.starts_with('+')) token.remove_prefix(1);
        double v = 0.0;
        const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
        const bool number = !token.empty() && end == token.data() + token.size() &&
                            (ec == std::errc() || ec == std::errc::result_out_of_range);
        if (!number) return shown(text) + " is not a number" + range;
        if (ec == std::errc() && !std::isfinite(v))
          return shown(text) + " is not a finite number" + range;
        if (ec == std::errc::result_out_of_range || v < lo || v > hi)
          return shown(text) + " is out of range" + range;
        return {};
      },
      "NUMBER in [" + number_text(lo) + " - " + number_text(hi) + "]", "FINITE");
}

CLI::Validator non_empty_path() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        return text.empty() ? std::string("an empty path (name a file)") : std::string();
      },
      "PATH", "PATH");
}

void add_columns_option(CLI::App& cmd, std::vector<std::string>& names) {
  cmd.add_option_function<std::string>(
      "--columns",
      [&names](const std::string& text) {
        // Every name given, none empty: `--columns ''` is a mistake (an unset
        // shell variable), not "no mapping".
        names.clear();
        std::size_t at = 0;
        do {
          const std::size_t end = std::min(text.find(',', at), text.size());
          if (end == at)
            throw InputError("--columns '" + text + "': an empty column name (give x,y,z,...)");
          names.push_back(text.substr(at, end - at));
          at = end + 1;
        } while (at <= text.size());
      },
      "A text cloud's columns in order, e.g. x,y,z,intensity,_,r,g,b (x y z, r g b, nx ny nz, any "
      "other name an attribute, _ skipped); replaces its header");
}

void add_crs_option(CLI::App& cmd, std::string& crs) {
  cmd.add_option("--crs", crs,
                 "Draw in this coordinate system (EPSG:32633, a WKT or a PROJ string): a file "
                 "that names its own is reprojected; default: geographic input goes to the UTM "
                 "zone of its centre, projected input stays as it is")
      ->check(CLI::Validator(
          [](const std::string& v) { return v.empty() ? std::string("an empty --crs") : ""; },
          "CRS"));
}

namespace {

// A size option (bytes, or K, M, G, T), above zero.
CLI::Option* add_size_option(CLI::App& cmd, const std::string& name, std::uint64_t& bytes,
                             const std::string& help) {
  return cmd
      .add_option_function<std::string>(
          name,
          [&bytes, name](const std::string& text) {
            const std::optional<std::uint64_t> v = parse_byte_size(text);
            if (!v || *v == 0)
              throw CLI::ValidationError(name,
                                         "'" + text + "' is not a size (bytes, or K, M, G, T)");
            bytes = *v;
          },
          help)
      ->type_name("SIZE");
}

}  // namespace

void add_memory_option(CLI::App& cmd, std::uint64_t& bytes, bool draws) {
  add_size_option(
      cmd, "--memory", bytes,
      std::string("The memory a build may use (bytes, or K, M, G, T; default: a quarter of "
                  "the machine's): a model that would need more is built in chunks into its "
                  "cache") +
          (draws ? "; a cache (.tch) given with it is drawn from its pages within it" : ""));
}

void add_gpu_memory_options(CLI::App& cmd, std::uint64_t& gpu, std::uint64_t& upload) {
  add_size_option(cmd, "--gpu-memory", gpu,
                  "A cache drawn from its pages (--memory): the GPU memory of its nodes (32 "
                  "bytes a node; default: room for every node --memory holds; less: the memory "
                  "holds no more nodes than it draws)");
  add_size_option(cmd, "--gpu-upload", upload,
                  "A cache drawn from its pages: the bytes copied to the GPU in a frame at most "
                  "(default 8M)");
}

}  // namespace treecut::cli
