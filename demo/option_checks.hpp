// Checks of numeric options, in place of CLI::Range, which lets NaN through
// (every comparison with NaN is false) and reports "1e3" for a whole-number
// option as "not in range". Each names the token and what was expected:
// "'1e3' is not a whole number (a whole number from 1 to 1000000)",
// "'nan' is not a finite number (a number from 0.1 to 3600)".
#pragma once

#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>
#include <vector>

namespace treecut::cli {

/// A whole number in [LO, HI] (decimal digits, an optional '+').
CLI::Validator whole_number(std::uint64_t lo, std::uint64_t hi);

/// A finite number in [LO, HI] (what std::from_chars reads: 2, 0.5, 1e3).
CLI::Validator finite_number(double lo, double hi);

/// A path that is not the empty string: '' is a mistake (an unset shell
/// variable), never "the default".
CLI::Validator non_empty_path();

/// `--columns x,y,z,intensity,_`: a text cloud's columns, in order (any
/// model command that opens a file). Into NAMES, split at the commas; an
/// empty name is refused.
void add_columns_option(CLI::App& cmd, std::vector<std::string>& names);

/// `--crs EPSG:32633`: the coordinate system to draw in (OpenOptions::crs).
void add_crs_option(CLI::App& cmd, std::string& crs);

/// `--memory 8G`: the bytes a build may use (OpenOptions::memory); with
/// DRAWS (view, render), also what a cache given with it is drawn from its
/// pages within (PagingOptions::memory_bytes).
void add_memory_option(CLI::App& cmd, std::uint64_t& bytes, bool draws = false);
/// `--gpu-memory 1G --gpu-upload 8M`: a paged model's GPU pool and the
/// bytes it copies up a frame (splat::GpuPoolOptions).
void add_gpu_memory_options(CLI::App& cmd, std::uint64_t& gpu, std::uint64_t& upload);

}  // namespace treecut::cli
