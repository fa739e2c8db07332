// treecut for a program that embeds it: everything docs/embedding.md uses in
// one include. The model (PLY import, the hierarchy and its cache, the cut),
// the stage and its strategies (the Controller, the Feedback Stage, the
// registry, the built-in strategies and plugins), and the View (GL contexts,
// the splat renderer, the render thread's frame, cameras, images).
//
//     find_package(treecut CONFIG REQUIRED)
//     target_link_libraries(my_viewer PRIVATE treecut::treecut)
//
// It sits above every layer (docs/architecture.md, "## Layers"); the
// libraries themselves never include it.
#pragma once

#include "treecut/controller.hpp"
#include "treecut/error.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/model.hpp"
#include "treecut/model_io.hpp"
#include "treecut/plugin.hpp"
#include "treecut/registry.hpp"
#include "treecut/scene.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/query_executor.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/strategies/builtin.hpp"
#include "treecut/strategy.hpp"
#include "treecut/tree_cut.hpp"
#include "treecut/view_snapshot.hpp"
