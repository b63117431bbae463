// Drawing 3D map objects into a TerrainRenderer frame: instanced icon quads, FreeType label
// glyphs from an atlas (halo pass, then text), and lit object meshes.
#include "terralod/render/object_renderer.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "gl_api.hpp"
#include "glyph_atlas.hpp"
#include "image_channels.hpp"

namespace terralod::render {
namespace {

const char* kIconVertex = R"(#version 330 core
layout(location = 0) in vec3 a_corner;  // u in [-0.5, 0.5], v in [0, 1], quad index
layout(location = 1) in vec4 a_inst;    // anchor relative to the camera (xyz), height in metres
uniform mat4 u_mvp;                     // clip from camera-relative world coordinates
uniform int u_quads;
uniform float u_aspect;                 // image width / height
uniform vec2 u_cam_right;
out vec2 v_uv;
void main() {
  vec2 right;
  if (u_quads == 1) {  // face the camera, turning about the vertical axis only
    vec2 d = -a_inst.xy;
    float l = length(d);
    right = l > 1e-3 ? vec2(-d.y, d.x) / l : u_cam_right;
  } else {
    float a = a_corner.z * 3.14159265358979 / float(u_quads);
    right = vec2(cos(a), sin(a));
  }
  float h = a_inst.w, w = h * u_aspect;
  vec3 p = a_inst.xyz + vec3(right * (a_corner.x * w), a_corner.y * h);
  v_uv = vec2(a_corner.x + 0.5, 1.0 - a_corner.y);
  gl_Position = u_mvp * vec4(p, 1.0);
}
)";

const char* kIconFragment = R"(#version 330 core
in vec2 v_uv;
uniform sampler2D u_image;
uniform float u_cutoff;
out vec4 o_color;
void main() {
  vec4 c = texture(u_image, v_uv);
  if (c.a < u_cutoff) discard;
  o_color = vec4(c.rgb, 1.0);
}
)";

const char* kLabelVertex = R"(#version 330 core
layout(location = 0) in vec2 a_corner;  // (0|1, 0|1)
layout(location = 1) in vec4 a_rect;    // pixels x0, y0, x1, y1 (top-left origin)
layout(location = 2) in vec4 a_uv;      // atlas u0, v0, u1, v1 (normalised)
layout(location = 3) in float a_depth;  // normalised device z of the label's depth point
uniform vec2 u_viewport;
out vec2 v_uv;
void main() {
  vec2 p = mix(a_rect.xy, a_rect.zw, a_corner);
  v_uv = mix(a_uv.xy, a_uv.zw, a_corner);
  gl_Position = vec4(2.0 * p.x / u_viewport.x - 1.0, 1.0 - 2.0 * p.y / u_viewport.y, a_depth, 1.0);
}
)";

const char* kLabelFragment = R"(#version 330 core
in vec2 v_uv;
uniform sampler2D u_atlas;  // r: glyph coverage, g: halo coverage
uniform int u_pass;         // 0: halo, 1: text
uniform vec4 u_color;
out vec4 o_color;
void main() {
  vec2 t = texture(u_atlas, v_uv).rg;
  float a = (u_pass == 0 ? t.g : t.r) * u_color.a;
  if (a <= 0.0) discard;
  o_color = vec4(u_color.rgb, a);
}
)";

const char* kMeshVertex = R"(#version 330 core
layout(location = 0) in vec3 a_pos;     // relative to the camera
layout(location = 1) in vec3 a_normal;
uniform mat4 u_mvp;
out vec3 v_pos;
out vec3 v_normal;
void main() {
  v_pos = a_pos;
  v_normal = a_normal;
  gl_Position = u_mvp * vec4(a_pos, 1.0);
}
)";

const char* kMeshFragment = R"(#version 330 core
in vec3 v_pos;
in vec3 v_normal;
uniform int u_has_normals;
uniform vec3 u_light;
uniform float u_ambient;
uniform vec4 u_color;
out vec4 o_color;
void main() {
  // Flat: the triangle's plane from the screen derivatives, facing the viewer.
  vec3 n = u_has_normals == 1 ? normalize(v_normal) : normalize(cross(dFdx(v_pos), dFdy(v_pos)));
  float diffuse = max(dot(n, u_light), 0.0);
  o_color = vec4(u_color.rgb * (u_ambient + (1.0 - u_ambient) * diffuse), u_color.a);
}
)";

const auto offset = [](std::size_t bytes) { return reinterpret_cast<const void*>(bytes); };

/// A growable array buffer: one BufferData (new storage) per call, capacity grows by 1.5x.
struct StreamBuffer {
  GLuint id = 0;
  std::size_t capacity = 0;
  std::size_t write(const detail::GlApi& gl, GLenum target, const void* data, std::size_t bytes) {
    gl.BindBuffer(target, id);
    if (bytes > capacity) capacity = std::max(bytes, capacity + capacity / 2);
    gl.BufferData(target, GLsizeiptr(capacity), nullptr, GL_STREAM_DRAW);
    if (bytes) gl.BufferSubData(target, 0, GLsizeiptr(bytes), data);
    return bytes;
  }
};

struct IconStyleGpu {
  GLuint texture = 0;
  int quads = 1;
  float aspect = 1.0f;
};

/// Depth convention of a frame: GL depth test passing the nearer (or equal) fragment.
GLenum depth_func(const FrameTarget& f) { return f.reverse_z ? GL_GEQUAL : GL_LEQUAL; }

/// Clip from camera-relative world coordinates, formed in doubles and only then rounded.
glm::mat4 camera_relative_mvp(const FrameTarget& f) {
  return glm::mat4(f.view_projection * glm::translate(glm::dmat4(1.0), camera_position(f.camera)));
}

}  // namespace

std::optional<ScreenPoint> project_point(const Camera& camera, const glm::dvec3& world) {
  const glm::dvec4 eye = view_matrix(camera) * glm::dvec4(world, 1.0);
  if (!(-eye.z > camera.near_m)) return std::nullopt;
  const glm::dvec4 clip = projection_matrix(camera) * eye;
  const double nx = clip.x / clip.w, ny = clip.y / clip.w;
  return ScreenPoint{(nx + 1.0) * 0.5 * camera.width_px, (1.0 - ny) * 0.5 * camera.height_px, -eye.z};
}

RgbaImage default_marker_image(int size) {
  assert(size >= 8 && "default_marker_image: size must be >= 8");
  RgbaImage img(size, size);
  const double s = size, cx = s * 0.5, cy = s * 0.36, r = s * 0.32;  // head circle; tip at (cx, s)
  for (int y = 0; y < size; ++y)
    for (int x = 0; x < size; ++x) {
      const double px = x + 0.5, py = y + 0.5, d = std::hypot(px - cx, py - cy);
      // Below the head's centre the pin narrows linearly from r to 0 at the bottom row.
      const double half = py > cy ? r * (s - py) / (s - cy) : -1.0;
      const bool inside = d <= r || std::abs(px - cx) <= half;
      if (!inside) {
        img.set(x, y, {120, 20, 10, 0});  // transparent, the rim's colour (no dark mipmap fringe)
        continue;
      }
      const double rim = std::max(r - d, half - std::abs(px - cx));  // distance inside the outline
      if (d <= r * 0.38)
        img.set(x, y, {255, 255, 255, 255});  // white dot
      else if (rim < s / 24.0)
        img.set(x, y, {120, 20, 10, 255});  // dark rim
      else
        img.set(x, y, {225, 55, 35, 255});  // red body
    }
  return img;
}

struct ObjectRenderer::Impl {
  const detail::GlApi& gl;
  detail::GlyphAtlas atlas;
  GLuint icon_program = 0, label_program = 0, mesh_program = 0;
  GLuint icon_vao = 0, label_vao = 0, mesh_vao = 0;
  GLuint icon_corners = 0, label_corners = 0;
  StreamBuffer icon_instances, label_instances, mesh_vertices, mesh_indices;
  GLuint atlas_texture = 0;
  std::uint64_t atlas_uploaded = ~std::uint64_t(0);
  std::vector<IconStyleGpu> styles;  // IconStyleId v -> styles[v - 1]

  Impl(const detail::GlApi& api, const ObjectRendererOptions& o) : gl(api), atlas(o.font, o.halo_px) {}

  GLint loc(GLuint program, const char* name) const { return gl.GetUniformLocation(program, name); }

  void build() {
    icon_program = detail::build_program(gl, kIconVertex, kIconFragment, "object renderer (icons)");
    label_program = detail::build_program(gl, kLabelVertex, kLabelFragment, "object renderer (labels)");
    mesh_program = detail::build_program(gl, kMeshVertex, kMeshFragment, "object renderer (meshes)");
    GLuint vaos[3];
    gl.GenVertexArrays(3, vaos);
    icon_vao = vaos[0], label_vao = vaos[1], mesh_vao = vaos[2];
    GLuint bufs[6];
    gl.GenBuffers(6, bufs);
    icon_corners = bufs[0], label_corners = bufs[1], icon_instances.id = bufs[2],
    label_instances.id = bufs[3];
    mesh_vertices.id = bufs[4], mesh_indices.id = bufs[5];

    // Icons: 6 corners per quad, up to 3 quads; instances: anchor + height.
    std::vector<float> corners;
    for (int q = 0; q < 3; ++q)
      for (const auto& [u, v] :
           {std::pair{-0.5f, 0.0f}, {0.5f, 0.0f}, {0.5f, 1.0f}, {-0.5f, 0.0f}, {0.5f, 1.0f}, {-0.5f, 1.0f}})
        corners.insert(corners.end(), {u, v, float(q)});
    gl.BindVertexArray(icon_vao);
    gl.BindBuffer(GL_ARRAY_BUFFER, icon_corners);
    gl.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(corners.size() * 4), corners.data(), GL_STATIC_DRAW);
    gl.EnableVertexAttribArray(0);
    gl.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 12, offset(0));
    gl.EnableVertexAttribArray(1);
    gl.VertexAttribDivisor(1, 1);

    // Labels: a unit square; instances: rect, uv rect, depth (9 floats).
    const float square[12] = {0, 0, 1, 0, 1, 1, 0, 0, 1, 1, 0, 1};
    gl.BindVertexArray(label_vao);
    gl.BindBuffer(GL_ARRAY_BUFFER, label_corners);
    gl.BufferData(GL_ARRAY_BUFFER, sizeof(square), square, GL_STATIC_DRAW);
    gl.EnableVertexAttribArray(0);
    gl.VertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 8, offset(0));
    gl.BindBuffer(GL_ARRAY_BUFFER, label_instances.id);
    for (GLuint a = 1; a <= 3; ++a) {
      gl.EnableVertexAttribArray(a);
      gl.VertexAttribDivisor(a, 1);
    }
    gl.VertexAttribPointer(1, 4, GL_FLOAT, GL_FALSE, 36, offset(0));
    gl.VertexAttribPointer(2, 4, GL_FLOAT, GL_FALSE, 36, offset(16));
    gl.VertexAttribPointer(3, 1, GL_FLOAT, GL_FALSE, 36, offset(32));

    // Meshes: position + normal (24 bytes), 32-bit indices.
    gl.BindVertexArray(mesh_vao);
    gl.BindBuffer(GL_ARRAY_BUFFER, mesh_vertices.id);
    gl.EnableVertexAttribArray(0);
    gl.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 24, offset(0));
    gl.EnableVertexAttribArray(1);
    gl.VertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 24, offset(12));
    gl.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, mesh_indices.id);
    gl.BindVertexArray(0);

    gl.GenTextures(1, &atlas_texture);
    detail::check_gl(gl, "object renderer: creating buffers");
  }

  void release() {
    for (const IconStyleGpu& s : styles) gl.DeleteTextures(1, &s.texture);
    gl.DeleteTextures(1, &atlas_texture);
    const GLuint bufs[6] = {icon_corners,       label_corners,    icon_instances.id,
                            label_instances.id, mesh_vertices.id, mesh_indices.id};
    gl.DeleteBuffers(6, bufs);
    const GLuint vaos[3] = {icon_vao, label_vao, mesh_vao};
    gl.DeleteVertexArrays(3, vaos);
    gl.DeleteProgram(icon_program);
    gl.DeleteProgram(label_program);
    gl.DeleteProgram(mesh_program);
  }

  /// Uploads the glyph atlas when it changed since the last upload; returns the bytes sent.
  std::size_t sync_atlas() {
    if (atlas.version() == atlas_uploaded) return 0;
    gl.BindTexture(GL_TEXTURE_2D, atlas_texture);
    gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RG8, detail::GlyphAtlas::kWidth, atlas.height(), 0, GL_RG,
                  GL_UNSIGNED_BYTE, atlas.texels().data());
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    atlas_uploaded = atlas.version();
    return atlas.texels().size();
  }

  /// Common state of the object passes: the frame's depth test, no culling, filled polygons.
  void begin(const FrameTarget& f) {
    gl.Enable(GL_DEPTH_TEST);
    gl.DepthFunc(depth_func(f));
    gl.Disable(GL_CULL_FACE);
    gl.PolygonMode(GL_FRONT_AND_BACK, GL_FILL);
  }
  void end(bool finish, const char* what) {
    gl.BindVertexArray(0);
    gl.Disable(GL_BLEND);
    gl.DepthMask(GL_TRUE);
    gl.Disable(GL_POLYGON_OFFSET_FILL);
    if (finish) gl.Finish();
    detail::check_gl(gl, what);
  }
};

ObjectRenderer::ObjectRenderer(GlContext& context, const ObjectRendererOptions& options)
    : ctx_(context), options_(options) {
  if (options.halo_px < 0 || options.halo_px > 8)
    throw std::invalid_argument("ObjectRenderer: halo_px " + std::to_string(options.halo_px) +
                                " is outside 0..8");
  if (!(options.icon_alpha_cutoff > 0.0f && options.icon_alpha_cutoff <= 1.0f))
    throw std::invalid_argument("ObjectRenderer: icon_alpha_cutoff must be in (0, 1]");
  if (!(options.label_depth_share >= 0.0 && options.label_depth_share < 1.0))
    throw std::invalid_argument("ObjectRenderer: label_depth_share must be in [0, 1)");
  ctx_.make_current();
  impl_ = std::make_unique<Impl>(ctx_.api(), options_);
  try {
    impl_->build();
  } catch (...) {
    impl_->release();
    throw;
  }
}

ObjectRenderer::~ObjectRenderer() {
  ctx_.make_current();
  impl_->release();
}

IconStyleId ObjectRenderer::add_icon_style(const RgbaImage& image, int quads) {
  if (quads < 1 || quads > 3)
    throw std::invalid_argument("ObjectRenderer: an icon has 1 to 3 quads, not " + std::to_string(quads));
  if (image.width < 1 || image.height < 1 || image.rgba.size() != std::size_t(image.width) * image.height * 4)
    throw std::invalid_argument(
        "ObjectRenderer: the icon image is empty or its size does not match its pixels");
  ctx_.make_current();
  const detail::GlApi& gl = impl_->gl;
  IconStyleGpu s;
  s.quads = quads;
  s.aspect = float(image.width) / float(image.height);
  gl.GenTextures(1, &s.texture);
  gl.BindTexture(GL_TEXTURE_2D, s.texture);
  gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
  gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, image.width, image.height, 0, GL_RGBA, GL_UNSIGNED_BYTE,
                image.rgba.data());
  gl.GenerateMipmap(GL_TEXTURE_2D);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  detail::check_gl(gl, "object renderer: uploading an icon image");
  impl_->styles.push_back(s);
  return IconStyleId{std::uint32_t(impl_->styles.size())};
}

IconStyleId ObjectRenderer::load_icon_style(const std::string& path, int quads) {
  const detail::ChannelPixels in = detail::read_channel_pixels(path, "the icon image");
  RgbaImage img(in.width, in.height);
  for (std::size_t p = 0; p < std::size_t(img.width) * img.height; ++p)
    in.channels.to_rgba(&in.pixels[p * in.channels.read], &img.rgba[4 * p]);
  return add_icon_style(img, quads);
}

glm::ivec2 ObjectRenderer::measure_label(std::string_view text, int size_px) {
  if (size_px < 1)
    throw std::invalid_argument("ObjectRenderer: label size " + std::to_string(size_px) + " px");
  const detail::LabelLayout l = impl_->atlas.layout(text, size_px);
  return {l.width, l.height};
}

namespace {
/// The label's top-left pixel: centred on the anchor, baseline `offset_px` above it.
glm::ivec2 label_origin(const glm::dvec2& anchor, const detail::LabelLayout& l, int offset_px) {
  return {int(std::lround(anchor.x - 0.5 * l.width)), int(std::lround(anchor.y)) - offset_px - l.baseline_y};
}
}  // namespace

PixelBox ObjectRenderer::label_rect(const glm::dvec2& anchor_px, std::string_view text, int size_px) {
  if (size_px < 1)
    throw std::invalid_argument("ObjectRenderer: label size " + std::to_string(size_px) + " px");
  const detail::LabelLayout l = impl_->atlas.layout(text, size_px);
  if (l.glyphs.empty()) return {};
  const glm::ivec2 o = label_origin(anchor_px, l, options_.label_offset_px);
  return {o.x, o.y, o.x + l.width, o.y + l.height};
}

ObjectDrawStats ObjectRenderer::draw_icons(FrameSource& frame, std::span<const IconInstance> icons) {
  ObjectDrawStats stats;
  for (const IconInstance& i : icons) {
    if (i.style.value == 0 || i.style.value > impl_->styles.size())
      throw std::invalid_argument("ObjectRenderer: icon style " + std::to_string(i.style.value) +
                                  " is unknown");
    if (!(i.size_m > 0.0) || !std::isfinite(i.size_m))
      throw std::invalid_argument("ObjectRenderer: icon size " + std::to_string(i.size_m) + " m is not > 0");
  }
  if (icons.empty()) return stats;
  const FrameTarget f = frame.bind_frame();
  const detail::GlApi& gl = impl_->gl;
  const glm::dvec3 origin = camera_position(f.camera);
  // Instances grouped by style (a stable order: equal inputs give equal frames).
  std::vector<std::uint32_t> order(icons.size());
  for (std::uint32_t k = 0; k < order.size(); ++k) order[k] = k;
  std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    return icons[a].style.value < icons[b].style.value;
  });
  std::vector<float> inst;
  inst.reserve(4 * icons.size());
  for (const std::uint32_t k : order) {
    const glm::dvec3 rel = icons[k].anchor - origin;
    inst.insert(inst.end(), {float(rel.x), float(rel.y), float(rel.z), float(icons[k].size_m)});
  }
  stats.bytes_uploaded = impl_->icon_instances.write(gl, GL_ARRAY_BUFFER, inst.data(), inst.size() * 4);

  impl_->begin(f);
  gl.DepthMask(GL_TRUE);
  gl.Disable(GL_BLEND);
  gl.UseProgram(impl_->icon_program);
  const glm::mat4 mvp = camera_relative_mvp(f);
  gl.UniformMatrix4fv(impl_->loc(impl_->icon_program, "u_mvp"), 1, GL_FALSE, &mvp[0][0]);
  // The world offset that the view (through the ground scale) shows along the image's right.
  const glm::dvec3 right = f.camera.ground.inverse_apply(camera_right(f.camera));
  gl.Uniform2f(impl_->loc(impl_->icon_program, "u_cam_right"), float(right.x), float(right.y));
  gl.Uniform1f(impl_->loc(impl_->icon_program, "u_cutoff"), options_.icon_alpha_cutoff);
  gl.Uniform1i(impl_->loc(impl_->icon_program, "u_image"), 0);
  gl.ActiveTexture(GL_TEXTURE0);
  gl.BindVertexArray(impl_->icon_vao);
  gl.BindBuffer(GL_ARRAY_BUFFER, impl_->icon_instances.id);
  for (std::size_t first = 0; first < order.size();) {
    const std::uint32_t style = icons[order[first]].style.value;
    std::size_t last = first;
    while (last < order.size() && icons[order[last]].style.value == style) ++last;
    const IconStyleGpu& s = impl_->styles[style - 1];
    gl.VertexAttribPointer(1, 4, GL_FLOAT, GL_FALSE, 16, offset(first * 16));
    gl.Uniform1i(impl_->loc(impl_->icon_program, "u_quads"), s.quads);
    gl.Uniform1f(impl_->loc(impl_->icon_program, "u_aspect"), s.aspect);
    gl.BindTexture(GL_TEXTURE_2D, s.texture);
    gl.DrawArraysInstanced(GL_TRIANGLES, 0, 6 * s.quads, GLsizei(last - first));
    ++stats.draw_calls;
    first = last;
  }
  stats.objects = icons.size();
  impl_->end(options_.finish, "object renderer: drawing icons");
  return stats;
}

ObjectDrawStats ObjectRenderer::draw_labels(FrameSource& frame, std::span<const LabelInstance> labels) {
  ObjectDrawStats stats;
  for (const LabelInstance& l : labels)
    if (l.size_px < 1)
      throw std::invalid_argument("ObjectRenderer: label \"" + l.text + "\" has size " +
                                  std::to_string(l.size_px) + " px");
  if (labels.empty()) return stats;
  const FrameTarget f = frame.bind_frame();
  const detail::GlApi& gl = impl_->gl;
  const glm::dvec3 eye = camera_position(f.camera);
  std::vector<float> inst;
  for (const LabelInstance& l : labels) {
    const std::optional<ScreenPoint> p = project_point(f.camera, l.anchor);
    if (!p) continue;
    const detail::LabelLayout lay = impl_->atlas.layout(l.text, l.size_px);
    if (lay.glyphs.empty()) continue;
    // Depth point: the anchor moved towards the camera, kept in front of the near plane.
    glm::dvec3 d = l.anchor + (eye - l.anchor) * options_.label_depth_share;
    if (const auto pd = project_point(f.camera, d); !pd) d = l.anchor;
    const glm::dvec4 clip = f.view_projection * glm::dvec4(d, 1.0);
    const float depth = float(clip.z / clip.w);
    const glm::ivec2 o = label_origin({p->x, p->y}, lay, options_.label_offset_px);
    for (const detail::PlacedGlyph& g : lay.glyphs) {
      const float w = float(detail::GlyphAtlas::kWidth);  // the atlas height is only known after layout
      inst.insert(inst.end(), {float(o.x + g.x0), float(o.y + g.y0), float(o.x + g.x1), float(o.y + g.y1),
                               float(g.atlas_x) / w, float(g.atlas_y), float(g.atlas_x + g.x1 - g.x0) / w,
                               float(g.atlas_y + g.y1 - g.y0), depth});
    }
    ++stats.objects;
  }
  // Atlas rows to normalised v, now that every glyph is in the atlas.
  const float h = float(impl_->atlas.height());
  for (std::size_t k = 0; k < inst.size(); k += 9) inst[k + 5] /= h, inst[k + 7] /= h;
  stats.bytes_uploaded = impl_->sync_atlas();
  const std::size_t glyphs = inst.size() / 9;
  if (glyphs == 0) return stats;
  stats.bytes_uploaded += impl_->label_instances.write(gl, GL_ARRAY_BUFFER, inst.data(), inst.size() * 4);

  impl_->begin(f);
  gl.DepthMask(GL_FALSE);
  gl.Enable(GL_BLEND);
  gl.BlendEquation(GL_FUNC_ADD);
  gl.BlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  gl.UseProgram(impl_->label_program);
  gl.Uniform2f(impl_->loc(impl_->label_program, "u_viewport"), float(f.camera.width_px),
               float(f.camera.height_px));
  gl.Uniform1i(impl_->loc(impl_->label_program, "u_atlas"), 0);
  gl.ActiveTexture(GL_TEXTURE0);
  gl.BindTexture(GL_TEXTURE_2D, impl_->atlas_texture);
  gl.BindVertexArray(impl_->label_vao);
  const GLint u_pass = impl_->loc(impl_->label_program, "u_pass");
  const GLint u_color = impl_->loc(impl_->label_program, "u_color");
  // Halos of every label first, so that no halo covers a neighbouring glyph's text.
  for (int pass = options_.halo_px > 0 ? 0 : 1; pass < 2; ++pass) {
    const glm::vec4 c = pass == 0 ? options_.halo_color : options_.text_color;
    gl.Uniform1i(u_pass, pass);
    gl.Uniform4f(u_color, c.r, c.g, c.b, c.a);
    gl.DrawArraysInstanced(GL_TRIANGLES, 0, 6, GLsizei(glyphs));
    ++stats.draw_calls;
  }
  impl_->end(options_.finish, "object renderer: drawing labels");
  return stats;
}

ObjectDrawStats ObjectRenderer::draw_mesh(FrameSource& frame, const blocks::ObjectMesh& mesh,
                                          const glm::vec4& color, const MeshStyle& style) {
  ObjectDrawStats stats;
  const std::size_t n = mesh.positions.size();
  if (!mesh.normals.empty() && mesh.normals.size() != n)
    throw std::invalid_argument("ObjectRenderer: the mesh has " + std::to_string(mesh.normals.size()) +
                                " normals for " + std::to_string(n) + " vertices");
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t)
    for (const std::uint32_t v : mesh.triangles[t])
      if (v >= n)
        throw std::invalid_argument("ObjectRenderer: mesh triangle " + std::to_string(t) + " uses vertex " +
                                    std::to_string(v) + " of " + std::to_string(n));
  if (mesh.triangles.empty()) return stats;
  const FrameTarget f = frame.bind_frame();
  const detail::GlApi& gl = impl_->gl;
  const glm::dvec3 origin = camera_position(f.camera);
  std::vector<float> v(6 * n);
  for (std::size_t i = 0; i < n; ++i) {
    const pm::Vec3& p = mesh.positions[i];
    v[6 * i] = float(p.x - origin.x), v[6 * i + 1] = float(p.y - origin.y),
          v[6 * i + 2] = float(p.z - origin.z);
    const pm::Vec3 nn = mesh.normals.empty() ? pm::Vec3{0, 0, 1} : mesh.normals[i];
    v[6 * i + 3] = float(nn.x), v[6 * i + 4] = float(nn.y), v[6 * i + 5] = float(nn.z);
  }
  stats.bytes_uploaded = impl_->mesh_vertices.write(gl, GL_ARRAY_BUFFER, v.data(), v.size() * 4);
  gl.BindVertexArray(impl_->mesh_vao);  // the element buffer binding is vertex array state
  stats.bytes_uploaded += impl_->mesh_indices.write(gl, GL_ELEMENT_ARRAY_BUFFER, mesh.triangles.data(),
                                                    mesh.triangles.size() * 12);

  impl_->begin(f);
  const bool blend = color.a < 1.0f;
  gl.DepthMask(blend ? GL_FALSE : GL_TRUE);
  if (blend) {
    gl.Enable(GL_BLEND);
    gl.BlendEquation(GL_FUNC_ADD);
    gl.BlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
  } else {
    gl.Disable(GL_BLEND);
  }
  if (style.on_terrain) {  // towards the camera: smaller depth, or larger with reverse-Z
    const float sign = f.reverse_z ? 1.0f : -1.0f;
    gl.Enable(GL_POLYGON_OFFSET_FILL);
    gl.PolygonOffset(sign * style.offset_factor, sign * style.offset_units);
  }
  gl.UseProgram(impl_->mesh_program);
  const glm::mat4 mvp = camera_relative_mvp(f);
  const glm::dvec3 light = glm::normalize(f.light_direction);
  gl.UniformMatrix4fv(impl_->loc(impl_->mesh_program, "u_mvp"), 1, GL_FALSE, &mvp[0][0]);
  gl.Uniform1i(impl_->loc(impl_->mesh_program, "u_has_normals"), mesh.normals.empty() ? 0 : 1);
  gl.Uniform3f(impl_->loc(impl_->mesh_program, "u_light"), float(light.x), float(light.y), float(light.z));
  gl.Uniform1f(impl_->loc(impl_->mesh_program, "u_ambient"), f.ambient);
  gl.Uniform4f(impl_->loc(impl_->mesh_program, "u_color"), color.r, color.g, color.b, color.a);
  gl.DrawElements(GL_TRIANGLES, GLsizei(mesh.triangles.size() * 3), GL_UNSIGNED_INT, nullptr);
  stats.draw_calls = 1;
  stats.objects = mesh.triangles.size();
  impl_->end(options_.finish, "object renderer: drawing a mesh");
  return stats;
}

}  // namespace terralod::render
