// Mesh files through Assimp into a Scene. See mesh_file.h and docs/meshes.md.
#include "core/mesh_file.h"

#include <sys/stat.h>

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include <fmt/format.h>

#include "core/database.h"
#include "core/mesh_readers.h"
#include "core/scene_file.h"
#include "core/scene_view.h"
#include "core/stop.h"

namespace raynode::core {

namespace {

/// The material a mesh without materials gets: grey, diffuse only.
constexpr Vec3 kDefaultColour{0.8f, 0.8f, 0.8f};
/// Faces between two stop-request checks.
constexpr std::size_t kStopCheckFaces = 1 << 16;

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

Vec3 to_vec(const aiVector3D& v) { return {v.x, v.y, v.z}; }

float clamp01(float x) { return std::isfinite(x) ? std::clamp(x, 0.0f, 1.0f) : 0.0f; }

/// Rec. 709 luminance of a colour.
float luminance(const aiColor3D& c) { return 0.2126f * c.r + 0.7152f * c.g + 0.0722f * c.b; }

/// True when the material is Assimp's stand-in for a file without materials.
bool is_default_material(const aiMaterial& m) {
  aiString name;
  return m.Get(AI_MATKEY_NAME, name) == AI_SUCCESS && std::string(name.C_Str()) == AI_DEFAULT_MATERIAL_NAME;
}

/// docs/meshes.md, "Materials".
Material map_material(const aiMaterial& m) {
  Material out;
  out.color = kDefaultColour;
  aiColor3D c;
  if (m.Get(AI_MATKEY_COLOR_DIFFUSE, c) == AI_SUCCESS) out.color = {clamp01(c.r), clamp01(c.g), clamp01(c.b)};
  out.kd = 1.0f;
  if (m.Get(AI_MATKEY_COLOR_SPECULAR, c) == AI_SUCCESS) out.ks = clamp01(luminance(c));
  float f = 0.0f;
  if (m.Get(AI_MATKEY_SHININESS, f) == AI_SUCCESS && std::isfinite(f) && f > 0.0f) out.shine = f;
  if (m.Get(AI_MATKEY_OPACITY, f) == AI_SUCCESS && std::isfinite(f) && f < 1.0f)
    out.transmittance = clamp01(1.0f - f);
  if (m.Get(AI_MATKEY_REFRACTI, f) == AI_SUCCESS && std::isfinite(f) && f > 0.0f) out.ior = f;
  return out;
}

/// Global transform of the node named `name` (identity when there is none).
aiMatrix4x4 node_transform(const aiScene& s, const aiString& name) {
  aiMatrix4x4 m;
  for (const aiNode* n = s.mRootNode ? s.mRootNode->FindNode(name) : nullptr; n != nullptr; n = n->mParent)
    m = n->mTransformation * m;
  return m;
}

/// Adds a file's faces to a Scene as triangles (docs/meshes.md, "Geometry").
struct MeshBuilder {
  const std::string& path;
  Scene scene;
  std::size_t points = 0, lines = 0, faces_seen = 0;
  bool used_default_material = false;
  std::vector<std::uint32_t> tris;  // triangulate_polygon's output, reused
  std::vector<Vec3> face_v, face_n;  // one face's vertices and normals, reused

  [[noreturn]] void fail(const std::string& why) const {
    throw std::runtime_error(fmt::format("cannot read mesh '{}': {}", path, why));
  }

  /// Makes `m` the material of the faces that follow.
  void use_material(const Material& m) {
    if (scene.materials.empty() || !(scene.materials.back() == m)) scene.materials.push_back(m);
  }
  void use_default_material() {
    Material m;
    m.color = kDefaultColour;
    used_default_material = true;
    use_material(m);
  }

  /// One triangle; `n` null or three normals as the file gives them.
  void add_triangle(const Vec3* v, const Vec3* n) {
    if (is_degenerate_polygon(v, 3)) {
      ++scene.dropped_degenerate;
      return;
    }
    Vec3 unit[3];
    bool smooth = n != nullptr;
    for (int k = 0; k < 3 && smooth; ++k) {
      if (!is_finite(n[k]) || !(max_component(abs(n[k])) > 0.0f)) smooth = false;
      else unit[k] = normalize_any(n[k]);
    }
    // Three equal normals are a facet normal (STL, flat OBJ faces): flat.
    if (smooth && !(unit[0] == unit[1] && unit[1] == unit[2])) scene.add_patch(v, unit, 3);
    else scene.add_polygon(v, 3);
  }

  /// One face of `count` vertices (1: a point, 2: a line, both skipped;
  /// more than 3: triangulated as NFF polygons are). `n` may be null.
  void add_face(const Vec3* v, const Vec3* n, std::uint32_t count) {
    if (++faces_seen % kStopCheckFaces == 0) throw_if_stopped(fmt::format("reading mesh '{}'", path));
    for (std::uint32_t k = 0; k < count; ++k)
      if (!is_finite(v[k])) fail(fmt::format("vertex ({}, {}, {}) is not finite", v[k].x, v[k].y, v[k].z));
    if (count == 1) { ++points; return; }
    if (count == 2) { ++lines; return; }
    if (count == 0) return;
    if (count == 3) { add_triangle(v, n); return; }
    tris.clear();
    try {
      triangulate_polygon(v, count, tris, false);
    } catch (const std::invalid_argument& e) {
      fail(e.what());
    }
    for (std::size_t t = 0; t + 2 < tris.size(); t += 3) {
      const Vec3 tv[3] = {v[tris[t]], v[tris[t + 1]], v[tris[t + 2]]};
      if (n == nullptr) {
        add_triangle(tv, nullptr);
      } else {
        const Vec3 tn[3] = {n[tris[t]], n[tris[t + 1]], n[tris[t + 2]]};
        add_triangle(tv, tn);
      }
    }
  }

  /// A MeshData (read_ply, read_off) with the default material.
  void add_mesh_data(const MeshData& m) {
    use_default_material();
    const bool normals = m.normals.size() == m.positions.size() && !m.normals.empty();
    const std::size_t triangles = m.face_indices.size() >= 2 * m.face_sizes.size()
                                      ? m.face_indices.size() - 2 * m.face_sizes.size()
                                      : 0;  // n - 2 per face of n >= 3 vertices
    scene.shapes.reserve(scene.shapes.size() + triangles);
    scene.vertices.reserve(scene.vertices.size() + 3 * triangles);
    if (normals) scene.normals.reserve(scene.normals.size() + 3 * triangles);
    std::size_t at = 0;
    for (const std::uint32_t count : m.face_sizes) {
      face_v.resize(count);
      face_n.resize(count);
      for (std::uint32_t k = 0; k < count; ++k) {
        const std::uint32_t i = m.face_indices[at + k];
        face_v[k] = m.positions[i];
        if (normals) face_n[k] = m.normals[i];
      }
      at += count;
      add_face(face_v.data(), normals ? face_n.data() : nullptr, count);
    }
  }

  /// An Assimp mesh under a node's global transform.
  void add_ai_mesh(const aiScene& ai, const aiMesh& mesh, const aiMatrix4x4& transform) {
    const bool identity = transform.IsIdentity();
    const aiMatrix3x3 normal_matrix = aiMatrix3x3(transform).Inverse().Transpose();
    const bool has_normals = mesh.HasNormals();
    const unsigned mi = mesh.mMaterialIndex;
    if (mi < ai.mNumMaterials && !is_default_material(*ai.mMaterials[mi])) {
      use_material(map_material(*ai.mMaterials[mi]));
    } else {
      use_default_material();
    }
    for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
      const aiFace& face = mesh.mFaces[f];
      face_v.resize(face.mNumIndices);
      face_n.resize(face.mNumIndices);
      for (unsigned k = 0; k < face.mNumIndices; ++k) {
        const unsigned i = face.mIndices[k];
        if (i >= mesh.mNumVertices) fail(fmt::format("face {} refers to vertex {} of {}", f, i, mesh.mNumVertices));
        face_v[k] = to_vec(identity ? mesh.mVertices[i] : transform * mesh.mVertices[i]);
        if (has_normals) face_n[k] = to_vec(identity ? mesh.mNormals[i] : normal_matrix * mesh.mNormals[i]);
      }
      add_face(face_v.data(), has_normals ? face_n.data() : nullptr, face.mNumIndices);
    }
  }

  void add_ai_node(const aiScene& ai, const aiNode& node, const aiMatrix4x4& parent) {
    const aiMatrix4x4 m = parent * node.mTransformation;
    for (unsigned i = 0; i < node.mNumMeshes; ++i)
      if (node.mMeshes[i] < ai.mNumMeshes) add_ai_mesh(ai, *ai.mMeshes[node.mMeshes[i]], m);
    for (unsigned i = 0; i < node.mNumChildren; ++i) add_ai_node(ai, *node.mChildren[i], m);
  }
};

/// Which reader a file goes to.
enum class MeshFormat { kPly, kOff, kAssimp };

MeshFormat mesh_format(const std::string& path, const std::string& head) {
  const std::string ext = lower_extension(path);
  if (ext == ".ply") return MeshFormat::kPly;
  if (ext == ".off") return MeshFormat::kOff;
  if (!is_mesh_extension(path)) {  // known by content only
    if (head.rfind("ply", 0) == 0) return MeshFormat::kPly;
    if (head.rfind("OFF", 0) == 0) return MeshFormat::kOff;
  }
  return MeshFormat::kAssimp;
}

/// The file's first bytes (at most 8).
std::string file_head(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  char head[8] = {};
  in.read(head, sizeof head);
  return std::string(head, std::size_t(in.gcount()));
}

}  // namespace

bool is_mesh_extension(const std::string& path) {
  const std::string ext = lower_extension(path);
  if (ext.empty() || ext == ".nff" || ext == ".gz") return false;
  static const Assimp::Importer importer;  // its format list only
  return importer.IsExtensionSupported(ext);
}

bool has_mesh_magic(const std::string& d) {
  auto starts = [&](const char* s) { return d.rfind(s, 0) == 0; };
  return ((starts("ply") || starts("OFF")) && d.size() > 3 && std::isspace(static_cast<unsigned char>(d[3]))) ||
         starts("glTF") || starts("solid ");
}

bool is_mesh_file(const std::string& path) {
  if (is_mesh_extension(path)) return true;
  const std::string ext = lower_extension(path);
  if (ext == ".nff" || ext == ".gz") return false;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) return false;  // FIFOs, devices: NFF's reader
  return has_mesh_magic(file_head(path));
}

Scene read_mesh(const std::string& path, std::vector<std::string>* notes, const ViewOverride& view) {
  auto fail = [&](const std::string& why) {
    throw std::runtime_error(fmt::format("cannot read mesh '{}': {}", path, why));
  };
  throw_if_stopped(fmt::format("reading mesh '{}'", path));
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) fail(std::strerror(errno));
  if (S_ISDIR(st.st_mode)) fail("it is a directory");
  const std::size_t limit = scene_text_limit_bytes();
  if (S_ISREG(st.st_mode) && std::size_t(st.st_size) > limit / 8)
    fail(fmt::format("it is {} MiB, more than {} MiB, an eighth of the most scene data this process can hold (a "
                     "mesh takes several times its file size)",
                     (std::size_t(st.st_size) >> 20) + 1, limit / 8 >> 20));

  MeshBuilder r{path, {}, 0, 0, 0, false, {}, {}, {}};
  Assimp::Importer importer;
  const aiScene* ai = nullptr;
  const MeshFormat format = mesh_format(path, file_head(path));
  if (format == MeshFormat::kAssimp) {
    // Assimp opens the file itself and would wait on a FIFO without a writer, deaf to the stop request.
    if (!S_ISREG(st.st_mode)) fail("Assimp reads only regular files");
    // Normals only as the file gives them; no unit scaling or recentring.
    ai = importer.ReadFile(path, aiProcess_Triangulate);
    if (ai == nullptr) {
      std::string why = importer.GetErrorString();
      std::replace(why.begin(), why.end(), '\n', ' ');
      while (!why.empty() && std::isspace(static_cast<unsigned char>(why.back()))) why.pop_back();
      fail(why.empty() ? "Assimp cannot import it" : why);
    }
    if (ai->mRootNode == nullptr) fail("the file holds no scene");
    r.add_ai_node(*ai, *ai->mRootNode, aiMatrix4x4());
  } else {
    const std::string bytes = read_scene_text(path, limit);
    r.add_mesh_data(format == MeshFormat::kPly ? read_ply(bytes, path) : read_off(bytes, path));
  }
  Scene& s = r.scene;
  if (s.shapes.empty()) {
    fail(fmt::format("it holds no triangles ({} degenerate dropped, {} points and {} lines skipped)",
                     s.dropped_degenerate, r.points, r.lines));
  }
  auto note = [&](const std::string& line) {
    if (notes) notes->push_back(line);
  };
  if (r.used_default_material)
    note(fmt::format("{} has no materials: using grey (colour {} {} {}, Kd 1)", path, kDefaultColour.x,
                     kDefaultColour.y, kDefaultColour.z));
  if (r.points + r.lines > 0) note(fmt::format("{}: skipped {} points and {} lines", path, r.points, r.lines));

  // The file's first perspective camera, if usable.
  for (unsigned i = 0; ai != nullptr && i < ai->mNumCameras && !s.has_view; ++i) {
    const aiCamera& cam = *ai->mCameras[i];
    if (!(cam.mHorizontalFOV > 0.0f)) continue;  // orthographic
    const aiMatrix4x4 m = node_transform(*ai, cam.mName);
    const aiMatrix3x3 m3(m);
    View v;
    v.from = to_vec(m * cam.mPosition);
    v.at = v.from + to_vec(m3 * cam.mLookAt);
    v.up = to_vec(m3 * cam.mUp);
    v.angle = float(2.0 * double(cam.mHorizontalFOV) * 180.0 / 3.14159265358979323846);
    v.width = 512;
    v.height = cam.mAspect > 0.0f ? std::clamp(int(std::lround(512.0 / cam.mAspect)), 1, 16384) : 512;
    if (view_problem(v).empty()) {
      s.view = v;
      s.has_view = true;
    } else {
      note(fmt::format("{}: camera '{}' ignored: {}", path, cam.mName.C_Str(), view_problem(v)));
    }
  }
  if (!s.has_view) {
    s.view = frame_bounds(s.bounds());
    s.has_view = true;
    if (!(view.eye && view.at)) note(fmt::format("{} has no view: framing its bounding box from +z", path));
  }
  // The command line's view now, so that default lights stand beside the eye it gives.
  apply_view_override(s, view);

  std::size_t other_lights = 0;
  for (unsigned i = 0; ai != nullptr && i < ai->mNumLights; ++i) {
    const aiLight& l = *ai->mLights[i];
    if (l.mType != aiLightSource_POINT && l.mType != aiLightSource_SPOT) {
      ++other_lights;
      continue;
    }
    Light out;
    out.position = to_vec(node_transform(*ai, l.mName) * l.mPosition);
    Vec3 c{l.mColorDiffuse.r, l.mColorDiffuse.g, l.mColorDiffuse.b};
    const float peak = max_component(c);
    if (!is_finite(c) || !(peak > 0.0f) || !is_finite(out.position)) {
      ++other_lights;
      continue;
    }
    if (peak > 1.0f) c = c / peak;  // NFF colours are 0..1: keep the hue
    out.color = c;
    out.has_color = true;
    s.lights.push_back(out);
  }
  if (other_lights > 0)
    note(fmt::format("{}: skipped {} lights that are not point or spot lights", path, other_lights));
  if (s.lights.empty()) {
    const View& v = s.view;
    const Vec3 dir = v.at - v.from;
    const float d = float(length_double(dir));
    const Vec3 right = normalize_any(cross(dir, v.up));
    const Vec3 up = normalize_any(cross(right, dir));
    s.lights.push_back(Light{v.from + (up + right) * (0.5f * d), {1, 1, 1}, false});
    s.lights.push_back(Light{v.from + (up * 0.5f - right) * (0.5f * d), {1, 1, 1}, false});
    note(fmt::format("{} has no lights: adding two white lights beside the eye", path));
  }
  return std::move(r.scene);
}

}  // namespace raynode::core
