// treecut view: camera controls (mouse, keys) and the files dropped on the window.
#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>

#include "messages.hpp"
#include "viewer_app.hpp"

namespace treecut::cli {

void Viewer::open_view() {
  if (scene_.sensor_view) {
    camera_ = *scene_.sensor_view;
  } else {
    fit();
  }
}

void Viewer::fit() {
  const glm::ivec2 size = window_.framebuffer_size();
  // A model's bounds, or a scene's (load_scene fills both).
  camera_ = splat::default_camera(scene_.view_min, scene_.view_max,
                                  float(size.x) / float(std::max(size.y, 1)), scene_.up);
}

// Turns the eye about the model's up axis (dx) and raises it towards the
// pole (dy), stopping short of it. Radians.
void Viewer::orbit(float dx, float dy) {
  const glm::vec3 up = scene_.up;
  glm::vec3 offset = camera_.eye - camera_.target;
  offset = glm::vec3(glm::rotate(glm::mat4(1.0f), -dx, up) * glm::vec4(offset, 0.0f));
  const float dist = glm::length(offset);
  const glm::vec3 side = glm::cross(up, offset);
  if (dist > 0.0f && glm::length(side) > 1e-6f * dist) {
    const float now = std::asin(std::clamp(glm::dot(offset, up) / dist, -1.0f, 1.0f));
    const float next = std::clamp(now + dy, -1.55f, 1.55f);
    offset = glm::vec3(glm::rotate(glm::mat4(1.0f), -(next - now), glm::normalize(side)) *
                       glm::vec4(offset, 0.0f));
  }
  camera_.eye = camera_.target + offset;
  camera_.up = up;
}

void Viewer::handle_input(double dt) {
  open_dropped();
  GLFWwindow* w = window_.handle();
  double x = 0.0, y = 0.0;
  glfwGetCursorPos(w, &x, &y);
  const glm::vec2 mouse(static_cast<float>(x), static_cast<float>(y));
  const glm::vec2 delta = have_mouse_ ? mouse - last_mouse_ : glm::vec2(0.0f);
  last_mouse_ = mouse;
  have_mouse_ = true;
  if (playing_ || !script_.empty()) return;  // the path or the script owns the camera
  // A press is new against the last frame's button, whoever had the mouse.
  const bool left = glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
  const bool clicked = left && !left_down_;
  left_down_ = left;
  if (!ImGui::GetIO().WantCaptureMouse) handle_mouse(glm::dvec2(x, y), delta, clicked);
  input_.scroll = 0.0;
  if (ImGui::GetIO().WantCaptureKeyboard) return;
  handle_keys();
  if (fly_) fly(dt);
}

void Viewer::open_dropped() {
  // A drop opens the last file dropped (several at once: the others are
  // named on stderr as ignored, not queued behind it).
  if (input_.dropped.empty()) return;
  for (std::size_t i = 0; i + 1 < input_.dropped.size(); ++i) {
    print_error(
        quoted_name(input_.dropped[i]) + ": ignored (several files dropped; opening the last)",
        true);
  }
  open_model(input_.dropped.back());
  input_.dropped.clear();
}

void Viewer::handle_mouse(glm::dvec2 cursor, glm::vec2 delta, bool clicked) {
  GLFWwindow* w = window_.handle();
  const bool left = left_down_;
  const bool ctrl = glfwGetKey(w, GLFW_KEY_LEFT_CONTROL) == GLFW_PRESS ||
                    glfwGetKey(w, GLFW_KEY_RIGHT_CONTROL) == GLFW_PRESS;
  if (ctrl) {
    // Ctrl+click picks (after this frame is drawn), in framebuffer pixels.
    if (clicked) {
      int ww = 1, wh = 1;
      glfwGetWindowSize(w, &ww, &wh);
      const glm::ivec2 fb = window_.framebuffer_size();
      pending_pick_ = glm::ivec2(static_cast<int>(cursor.x * fb.x / std::max(ww, 1)),
                                 static_cast<int>(cursor.y * fb.y / std::max(wh, 1)));
    }
    return;
  }
  if (left) {
    if (fly_) {
      const glm::vec3 f = camera_.forward();
      glm::mat4 rot = glm::rotate(glm::mat4(1.0f), -delta.x * 0.005f, scene_.up);
      const glm::vec3 right = glm::normalize(glm::cross(f, camera_.up));
      rot = glm::rotate(rot, -delta.y * 0.005f, right);
      const glm::vec3 nf = glm::vec3(rot * glm::vec4(f, 0.0f));
      camera_.target = camera_.eye + nf * glm::length(camera_.target - camera_.eye);
    } else {
      orbit(delta.x * 0.008f, delta.y * 0.008f);
    }
  }
  if (glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS ||
      glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS) {
    const glm::vec3 f = camera_.forward();
    const glm::vec3 right = glm::normalize(glm::cross(f, camera_.up));
    const glm::vec3 up = glm::cross(right, f);
    const float k = glm::length(camera_.eye - camera_.target) * 0.0015f;
    const glm::vec3 move = (-delta.x * right + delta.y * up) * k;
    camera_.eye += move;
    camera_.target += move;
  }
  if (input_.scroll != 0.0) {
    const glm::vec3 offset = camera_.eye - camera_.target;
    camera_.eye = camera_.target + offset * static_cast<float>(std::pow(0.88, input_.scroll));
  }
}

void Viewer::handle_keys() {
  GLFWwindow* w = window_.handle();
  auto pressed_once = [&](int key) {
    const bool down = glfwGetKey(w, key) == GLFW_PRESS;
    const bool was = keys_down_[key];
    keys_down_[key] = down;
    return down && !was;
  };
  if (pressed_once(GLFW_KEY_ESCAPE)) quit_ = true;
  const bool shift = glfwGetKey(w, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS ||
                     glfwGetKey(w, GLFW_KEY_RIGHT_SHIFT) == GLFW_PRESS;
  for (int slot = 1; slot <= 9; ++slot) {
    if (!pressed_once(GLFW_KEY_0 + slot)) continue;
    if (shift) {
      save_bookmark(slot);
    } else {
      go_to_bookmark(slot);
    }
  }
  if (pressed_once(GLFW_KEY_TAB)) fly_ = !fly_;
  if (pressed_once(GLFW_KEY_F)) fit();
  if (pressed_once(GLFW_KEY_U)) {
    // When --up auto guessed wrong: the next axis, and the view fitted to it.
    scene_.up_axis = next_up_axis(scene_.up_axis);
    scene_.up = scene_.up_axis.vector();
    if (color_by_.source == "elevation") recolor();
    fit();
  }
  if (pressed_once(GLFW_KEY_L)) {
    // Headlight -> fixed in the world -> unlit (the scan's own colours) -> headlight.
    splat::Light& l = settings_.light;
    if (l.unlit) {
      l.unlit = false;
      l.follow_camera = true;
    } else if (l.follow_camera) {
      l.follow_camera = false;
    } else {
      l.unlit = true;
    }
  }
  if (pressed_once(GLFW_KEY_H)) show_hud_ = !show_hud_;
  if (pressed_once(GLFW_KEY_F12) || pressed_once(GLFW_KEY_P)) {
    // The scene alone; with Shift, the window as shown (HUD included).
    pending_screenshot_ = next_name("png");
    screenshot_hud_ = shift;
  }
  if (pressed_once(GLFW_KEY_R)) toggle_recording();
  if (pressed_once(GLFW_KEY_SPACE)) start_playback();
  if (pressed_once(GLFW_KEY_O)) {
    // The next model named on the command line (the first after the last).
    if (models_.size() < 2) {
      say("O: name more models on the command line (treecut view A B), or drop a file");
    } else {
      model_index_ = (model_index_ + 1) % models_.size();
      open_model(models_[model_index_]);
    }
  }
}

void Viewer::fly(double dt) {
  GLFWwindow* w = window_.handle();
  const float speed = scene_.radius *
                      (glfwGetKey(w, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS ? 1.5f : 0.4f) *
                      static_cast<float>(dt);
  const glm::vec3 f = camera_.forward();
  const glm::vec3 right = glm::normalize(glm::cross(f, camera_.up));
  glm::vec3 move(0.0f);
  if (glfwGetKey(w, GLFW_KEY_W) == GLFW_PRESS) move += f;
  if (glfwGetKey(w, GLFW_KEY_S) == GLFW_PRESS) move -= f;
  if (glfwGetKey(w, GLFW_KEY_D) == GLFW_PRESS) move += right;
  if (glfwGetKey(w, GLFW_KEY_A) == GLFW_PRESS) move -= right;
  if (glfwGetKey(w, GLFW_KEY_E) == GLFW_PRESS) move += camera_.up;
  if (glfwGetKey(w, GLFW_KEY_Q) == GLFW_PRESS) move -= camera_.up;
  camera_.eye += move * speed;
  camera_.target += move * speed;
}

}  // namespace treecut::cli
