// OpenMesh stage of PLY import (see ply_openmesh.hpp).
#include "ply_openmesh.hpp"

#include <OpenMesh/Core/IO/IOManager.hh>
#include <OpenMesh/Core/IO/Options.hh>
#include <OpenMesh/Core/IO/importer/BaseImporter.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <algorithm>
#include <cstring>
#include <istream>
#include <mutex>
#include <streambuf>

namespace treecut::ply {

namespace {

using OpenMesh::EdgeHandle;
using OpenMesh::FaceHandle;
using OpenMesh::HalfedgeHandle;
using OpenMesh::VertexHandle;
using StatusInfo = OpenMesh::Attributes::StatusInfo;

// A read-only stream over consecutive pieces of memory, so the header we wrote
// and the body ranges of the file buffer reach OpenMesh without a copy.
// OpenMesh seeks back inside the header once (to find the first body byte),
// so seeking is supported across the whole sequence.
class PiecesBuffer final : public std::streambuf {
 public:
  explicit PiecesBuffer(const std::vector<std::string_view>& pieces) : pieces_(pieces) {
    std::size_t start = 0;
    for (std::string_view piece : pieces_) {
      starts_.push_back(start);
      start += piece.size();
    }
    total_ = start;
    if (!pieces_.empty()) select(0, 0);
  }

 protected:
  int_type underflow() override {
    while (gptr() == egptr()) {
      if (index_ + 1 >= pieces_.size()) return traits_type::eof();
      select(index_ + 1, 0);
    }
    return traits_type::to_int_type(*gptr());
  }

  std::streamsize xsgetn(char* out, std::streamsize count) override {
    // OpenMesh reads one value at a time: keep the common case to one copy.
    if (count <= egptr() - gptr()) {
      // Constant sizes let the compiler inline the copy of a float or an int.
      if (count == 4) {
        std::memcpy(out, gptr(), 4);
      } else if (count == 1) {
        *out = *gptr();
      } else {
        std::memcpy(out, gptr(), static_cast<std::size_t>(count));
      }
      setg(eback(), gptr() + count, egptr());
      return count;
    }
    std::streamsize done = 0;
    while (done < count) {
      if (gptr() == egptr() && traits_type::eq_int_type(underflow(), traits_type::eof())) break;
      const std::streamsize chunk = std::min<std::streamsize>(count - done, egptr() - gptr());
      std::memcpy(out + done, gptr(), static_cast<std::size_t>(chunk));
      setg(eback(), gptr() + chunk, egptr());
      done += chunk;
    }
    return done;
  }

  pos_type seekoff(off_type offset, std::ios_base::seekdir dir,
                   std::ios_base::openmode which) override {
    if (!(which & std::ios_base::in) || pieces_.empty()) return pos_type(off_type(-1));
    const auto current = static_cast<off_type>(starts_[index_]) + (gptr() - eback());
    off_type target = offset;
    if (dir == std::ios_base::cur) target += current;
    if (dir == std::ios_base::end) target += static_cast<off_type>(total_);
    if (target < 0 || target > static_cast<off_type>(total_)) return pos_type(off_type(-1));
    const auto position = static_cast<std::size_t>(target);
    // The last piece starting at or before POSITION (pieces may be empty).
    auto it = std::upper_bound(starts_.begin(), starts_.end(), position);
    const auto index = static_cast<std::size_t>(it - starts_.begin()) - 1;
    select(index, position - starts_[index]);
    return pos_type(target);
  }

  pos_type seekpos(pos_type position, std::ios_base::openmode which) override {
    return seekoff(off_type(position), std::ios_base::beg, which);
  }

 private:
  void select(std::size_t index, std::size_t offset) {
    index_ = index;
    // The get area is never written through (no putback of changed chars).
    char* begin = const_cast<char*>(pieces_[index].data());
    setg(begin, begin + offset, begin + pieces_[index].size());
  }

  const std::vector<std::string_view>& pieces_;
  std::vector<std::size_t> starts_;
  std::size_t total_ = 0;
  std::size_t index_ = 0;
};

// Stores what the reader reports straight into PointSet arrays that were sized
// from the validated header, and never grows them past that: a reader that
// delivered more rows than validated would be counted, not obeyed.
class PointSetImporter final : public OpenMesh::IO::BaseImporter {
 public:
  PointSetImporter(PointSet& points, const OpenMeshInput& input)
      : points_(points), vertices_(input.vertices) {
    points_.positions.assign(vertices_, glm::vec3(0.0f));
    if (input.normals) points_.normals.assign(vertices_, glm::vec3(0.0f));
    if (input.colors) points_.colors.assign(vertices_, glm::u8vec4(0, 0, 0, 255));
    points_.triangles.reserve(input.faces);
  }

  [[nodiscard]] const OpenMeshResult& result() const { return result_; }

  VertexHandle add_vertex(const OpenMesh::Vec3f& point) override {
    VertexHandle vh = add_vertex();
    set_point(vh, point);
    return vh;
  }

  VertexHandle add_vertex() override {
    const std::size_t index = result_.vertices_read++;
    return index < vertices_ ? VertexHandle(static_cast<int>(index)) : VertexHandle();
  }

  FaceHandle add_face(const VHandles& handles) override {
    ++result_.faces_read;
    if (handles.size() < 3) {
      ++result_.faces_degenerate;
    } else if (std::any_of(handles.begin(), handles.end(), [this](VertexHandle vh) {
                 return vh.idx() < 0 || static_cast<std::size_t>(vh.idx()) >= vertices_;
               })) {
      ++result_.faces_out_of_range;
    } else {
      // A polygon becomes a fan around its first vertex.
      const auto first = static_cast<unsigned>(handles[0].idx());
      for (std::size_t i = 1; i + 1 < handles.size(); ++i) {
        points_.triangles.emplace_back(first, static_cast<unsigned>(handles[i].idx()),
                                       static_cast<unsigned>(handles[i + 1].idx()));
      }
    }
    // OpenMesh only tests the handle for validity, to count "complex faces"
    // and print them to stderr; bad faces are reported by load_ply instead.
    return FaceHandle(0);
  }

  void set_point(VertexHandle vh, const OpenMesh::Vec3f& p) override {
    if (valid(vh)) points_.positions[index(vh)] = glm::vec3(p[0], p[1], p[2]);
  }

  void set_normal(VertexHandle vh, const OpenMesh::Vec3f& n) override {
    if (valid(vh) && !points_.normals.empty()) {
      points_.normals[index(vh)] = glm::vec3(n[0], n[1], n[2]);
    }
  }

  void set_normal(VertexHandle vh, const OpenMesh::Vec3d& n) override {
    set_normal(vh, OpenMesh::Vec3f(static_cast<float>(n[0]), static_cast<float>(n[1]),
                                   static_cast<float>(n[2])));
  }

  void set_color(VertexHandle vh, const OpenMesh::Vec4uc& c) override {
    // PointSet colors are opaque by contract; a file alpha is not kept.
    if (valid(vh) && !points_.colors.empty()) {
      points_.colors[index(vh)] = glm::u8vec4(c[0], c[1], c[2], 255);
    }
  }

  void set_color(VertexHandle vh, const OpenMesh::Vec3uc& c) override {
    set_color(vh, OpenMesh::Vec4uc(c[0], c[1], c[2], 255));
  }

  // The reader only calls the members above for the header we give it; the
  // rest of the interface (halfedges, texture coordinates, float colours,
  // status, face attributes) is deliberately inert.
  HalfedgeHandle add_edge(VertexHandle, VertexHandle) override { return HalfedgeHandle(); }
  FaceHandle add_face(HalfedgeHandle) override { return FaceHandle(); }
  void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<OpenMesh::Vec2f>&) override {}
  void add_face_texcoords(FaceHandle, VertexHandle, const std::vector<OpenMesh::Vec3f>&) override {}
  void set_face_texindex(FaceHandle, int) override {}
  void set_halfedge(VertexHandle, HalfedgeHandle) override {}
  void set_color(VertexHandle, const OpenMesh::Vec3f&) override {}
  void set_color(VertexHandle, const OpenMesh::Vec4f&) override {}
  void set_texcoord(VertexHandle, const OpenMesh::Vec2f&) override {}
  void set_status(VertexHandle, const StatusInfo&) override {}
  void set_next(HalfedgeHandle, HalfedgeHandle) override {}
  void set_face(HalfedgeHandle, FaceHandle) override {}
  void request_face_texcoords2D() override {}
  void set_texcoord(HalfedgeHandle, const OpenMesh::Vec2f&) override {}
  void set_texcoord(VertexHandle, const OpenMesh::Vec3f&) override {}
  void set_texcoord(HalfedgeHandle, const OpenMesh::Vec3f&) override {}
  void set_status(HalfedgeHandle, const StatusInfo&) override {}
  void set_color(EdgeHandle, const OpenMesh::Vec3uc&) override {}
  void set_color(EdgeHandle, const OpenMesh::Vec4uc&) override {}
  void set_color(EdgeHandle, const OpenMesh::Vec3f&) override {}
  void set_color(EdgeHandle, const OpenMesh::Vec4f&) override {}
  void set_status(EdgeHandle, const StatusInfo&) override {}
  void set_normal(FaceHandle, const OpenMesh::Vec3f&) override {}
  void set_normal(FaceHandle, const OpenMesh::Vec3d&) override {}
  void set_color(FaceHandle, const OpenMesh::Vec3uc&) override {}
  void set_color(FaceHandle, const OpenMesh::Vec4uc&) override {}
  void set_color(FaceHandle, const OpenMesh::Vec3f&) override {}
  void set_color(FaceHandle, const OpenMesh::Vec4f&) override {}
  void set_status(FaceHandle, const StatusInfo&) override {}
  void add_texture_information(int, std::string) override {}

  [[nodiscard]] size_t n_vertices() const override {
    return std::min(result_.vertices_read, vertices_);
  }
  [[nodiscard]] size_t n_faces() const override { return result_.faces_read; }
  [[nodiscard]] size_t n_edges() const override { return 0; }

 private:
  [[nodiscard]] bool valid(VertexHandle vh) const {
    return vh.idx() >= 0 && static_cast<std::size_t>(vh.idx()) < vertices_;
  }
  static std::size_t index(VertexHandle vh) { return static_cast<std::size_t>(vh.idx()); }

  PointSet& points_;
  std::size_t vertices_;
  OpenMeshResult result_;
};

}  // namespace

OpenMeshResult read_with_openmesh(const OpenMeshInput& input, PointSet& points) {
  std::vector<std::string_view> pieces;
  pieces.reserve(input.body.size() + 1);
  pieces.emplace_back(input.header);
  pieces.insert(pieces.end(), input.body.begin(), input.body.end());
  PiecesBuffer buffer(pieces);
  std::istream stream(&buffer);

  PointSetImporter importer(points, input);
  OpenMesh::IO::Options options;
  if (input.normals) options += OpenMesh::IO::Options::VertexNormal;
  if (input.colors) options += OpenMesh::IO::Options::VertexColor;

  // The reader is a process-wide singleton that keeps per-file state in
  // mutable members, and it toggles the global omerr() stream while reading.
  static std::mutex reader_mutex;
  bool ok = false;
  {
    std::lock_guard lock(reader_mutex);
    // Its diagnostics go to stderr; load_ply reports problems itself, one
    // line each, through the caller's WarningSink.
    const bool err_enabled = ::omerr().is_enabled();
    const bool log_enabled = ::omlog().is_enabled();
    ::omerr().disable();
    ::omlog().disable();
    ok = OpenMesh::IO::IOManager().read(stream, "ply", importer, options);
    if (err_enabled) ::omerr().enable();
    if (log_enabled) ::omlog().enable();
  }
  OpenMeshResult result = importer.result();
  result.reader_ok = ok;
  return result;
}

}  // namespace treecut::ply
