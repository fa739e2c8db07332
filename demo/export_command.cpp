// `treecut export MODEL -o OUT`: a point file converted to LAS, PLY or PCD
// (by OUT's extension), every attribute kept, optionally only some classes.
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "commands.hpp"
#include "messages.hpp"
#include "option_checks.hpp"
#include "output_checks.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/las.hpp"
#include "treecut/model_io.hpp"
#include "treecut/pcd.hpp"
#include "treecut/ply.hpp"
#include "treecut/splat/coloring.hpp"

namespace treecut::cli {

namespace {

struct ExportArgs {
  std::string model, out, classes;
  std::vector<std::string> columns;
  bool relative = false;
};

enum class Format { las, ply, pcd };

Format format_of(const std::filesystem::path& out) {
  std::string ext = out.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".las") return Format::las;
  if (ext == ".ply") return Format::ply;
  if (ext == ".pcd") return Format::pcd;
  throw InputError(quoted_name(out) + ": export writes .las, .ply or .pcd (by the name)");
}

// The points whose classification passes FILTER (splat::parse_class_filter's
// lists), every array kept in step (PointSet::keep_if).
std::size_t keep_classes(PointSet& p, const splat::ColorBy& filter, const std::string& model) {
  const PointAttribute* cls = nullptr;
  for (const PointAttribute& a : p.attributes) {
    if (a.name == "classification") cls = &a;
  }
  if (cls == nullptr)
    throw InputError(quoted_name(model) + ": --classes: no classification attribute");
  std::vector<bool> keep(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double v = cls->value(i);
    keep[i] = !splat::class_hidden(filter, std::isnan(v) ? -1 : static_cast<int>(std::lround(v)));
  }
  p.keep_if(keep);
  return p.size();
}

OwnFile own_file(Format format) {
  return format == Format::las ? is_own_las : format == Format::ply ? is_own_ply : is_own_pcd;
}

void run_export(const ExportArgs& a) {
  const std::filesystem::path model(a.model), out(a.out);
  const Format format = format_of(out);
  check_distinct_files({{out, "the export (-o)"}}, {{model, "the model"}});
  const char* kind = format == Format::las   ? "a LAS file"
                     : format == Format::ply ? "a PLY file"
                                             : "a PCD file";
  check_replaceable_output(out, own_file(format), "the export", kind);
  if (format == Format::las && a.relative)
    throw InputError("--relative: a LAS file holds the coordinates themselves; drop --relative");
  splat::ColorBy filter;
  if (!a.classes.empty()) splat::parse_class_filter(a.classes, filter);
  std::string read_as;
  PointSet points = load_point_file(
      model, [](const std::string& w) { print_warning(w); }, &read_as, a.columns);
  const std::size_t read = points.size();
  if (!a.classes.empty() && keep_classes(points, filter, a.model) == 0) {
    throw InputError(quoted_name(model) + ": --classes " + a.classes + " keeps no point");
  }
  if (out.has_parent_path()) {
    std::error_code ec;
    std::filesystem::create_directories(out.parent_path(), ec);
    if (ec) throw std::runtime_error(system_error_text(out.parent_path(), ec.value()));
  }
  SaveOptions options;
  options.relative = a.relative;
  switch (format) {
    case Format::las:
      save_las(out, points);
      break;
    case Format::ply:
      save_ply(out, points, options);
      break;
    case Format::pcd:
      save_pcd(out, points, PcdData::binary_compressed, options);
      break;
  }
  std::printf("wrote %s (%zu of %zu points, %zu attributes, from %s)\n", quoted_name(out).c_str(),
              points.size(), read, points.attributes.size(), read_as.c_str());
  const glm::dvec3 o = points.frame.origin;
  if (a.relative && o != glm::dvec3(0.0)) {
    std::printf(
        "origin %.3f %.3f %.3f: add it to the written positions for the file's coordinates\n", o.x,
        o.y, o.z);
  }
}

}  // namespace

void add_export_command(CLI::App& app) {
  auto args = std::make_shared<ExportArgs>();
  auto* cmd = app.add_subcommand(
      "export", "Convert a point file (PLY, LAS, PCD, text) to LAS, PLY or PCD, attributes kept");
  cmd->add_option("MODEL", args->model, "The point file")->check(non_empty_path())->required();
  cmd->add_option("-o,--output", args->out, "OUT.las, OUT.ply or OUT.pcd (binary_compressed)")
      ->check(non_empty_path())
      ->required();
  cmd->add_option("--classes", args->classes,
                  "Only these classes (2,6) or all but these (-7,-18) of the classification");
  add_columns_option(*cmd, args->columns);
  cmd->add_flag("--relative", args->relative,
                "PLY and PCD: write float positions relative to the model's origin (printed, and "
                "kept in a comment treecut reads back) for programs that read no doubles");
  cmd->callback([args] { run_export(*args); });
}

}  // namespace treecut::cli
