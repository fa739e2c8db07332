// A model's list of views (issue 30): the viewer's bookmarks, kept beside a
// model read from a file in MODEL.views, a camera path whose key times are
// the slots 1 to 9 (docs/camera-paths.md). GL-free, for the viewer and the
// tests.
//
// A user's data is sacred (issue 43, item 5): the file is written only when
// it is missing or when it reads whole as treecut's list of views, read
// again just before the write, so that what it held stays (a slot another
// viewer saved meanwhile). A file that does not read whole (a line that
// does not parse, past the text limit), a camera path of the user's (keys
// that are not slots), a symbolic link or anything that is not a regular
// file is never written over.
#pragma once

#include <array>
#include <filesystem>
#include <optional>

#include "treecut/splat/camera.hpp"

namespace treecut::cli {

using ViewSlots = std::array<std::optional<splat::Camera>, 9>;

/// Where the views of MODEL (the path it was opened by) are kept:
/// `MODEL.views` beside it; a folder of tiles opened as "tiles/" keeps them
/// beside the folder too, in `tiles.views`, not hidden inside it.
std::filesystem::path views_file_for(const std::filesystem::path& model);

/// The slots FILE holds (none when FILE is missing). Throws InputError
/// "FILE: why" when it exists and is not treecut's list of views, read whole.
ViewSlots read_views(const std::filesystem::path& file);

/// Keeps CAMERA as SLOT (1-9) in FILE: the slots FILE holds now
/// (read_views, which throws for a file that is not a list of views) with
/// this one set, written atomically; a read-only FILE is an InputError
/// too. Returns the slots written.
ViewSlots save_view(const std::filesystem::path& file, int slot, const splat::Camera& camera);

}  // namespace treecut::cli
