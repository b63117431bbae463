// GPU upload and drawing of terrain meshes: buffers, shaders, geomorphs, framebuffer, read-back.
// Compiled with -ffp-contract=off so that the CPU geomorph blend rounds like the shader's.
#include "terralod/render/terrain_renderer.hpp"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>

#include "gl_api.hpp"
#include "terralod/pm/timing.hpp"

namespace terralod::render {
namespace {

using Clock = std::chrono::steady_clock;
using pm::ms_since;

// Attribute locations. Static buffers: x, y, nx, ny, nz interleaved (20 bytes per vertex) and
// z0, z1 interleaved (8 bytes), so that new target heights rewrite only the second.
constexpr GLuint kXy = 0, kZ0 = 1, kZ1 = 2, kNormal = 3;
constexpr GLsizei kStride = 5 * sizeof(float), kZStride = 2 * sizeof(float);

const char* kVertexShader = R"(#version 330 core
layout(location = 0) in vec2 a_xy;
layout(location = 1) in float a_z0;
layout(location = 2) in float a_z1;
layout(location = 3) in vec3 a_normal;
uniform mat4 u_mvp;     // clip from mesh-relative coordinates (formed in doubles)
uniform float u_alpha;  // geomorph blend; 0 on the CPU path, whose a_z0 = a_z1 = blended z
uniform vec2 u_ramp;    // colour ramp parameter = z * u_ramp.x + u_ramp.y
out vec3 v_normal;
out float v_ramp;
void main() {
  // Same formula and rounding as the CPU path: exact endpoints at alpha = 0 and 1.
  float z = (1.0 - u_alpha) * a_z0 + u_alpha * a_z1;
  v_normal = a_normal;
  v_ramp = z * u_ramp.x + u_ramp.y;
  gl_Position = u_mvp * vec4(a_xy, z, 1.0);
}
)";

const char* kFragmentShader = R"(#version 330 core
in vec3 v_normal;
in float v_ramp;
uniform vec3 u_light;     // unit vector towards the light, world frame
uniform float u_ambient;
uniform float u_flat;     // 1: plain u_color (wireframe pass)
uniform vec3 u_color;
out vec4 o_color;
vec3 ramp(float t) {
  const vec3 green = vec3(0.27, 0.46, 0.22), brown = vec3(0.56, 0.47, 0.32);
  const vec3 rock = vec3(0.58, 0.57, 0.55), snow = vec3(0.96, 0.96, 0.97);
  if (t < 0.5) return mix(green, brown, t / 0.5);
  if (t < 0.85) return mix(brown, rock, (t - 0.5) / 0.35);
  return mix(rock, snow, (t - 0.85) / 0.15);
}
void main() {
  if (u_flat > 0.5) {
    o_color = vec4(u_color, 1.0);
    return;
  }
  vec3 n = normalize(v_normal);
  float diffuse = max(dot(n, u_light), 0.0);
  vec3 base = ramp(clamp(v_ramp, 0.0, 1.0));
  o_color = vec4(base * (u_ambient + (1.0 - u_ambient) * diffuse), 1.0);
}
)";

void check_indices(std::span<const std::uint32_t> indices, std::size_t vertices) {
  if (indices.size() % 3 != 0)
    throw std::invalid_argument("TerrainRenderer: " + std::to_string(indices.size()) +
                                " indices, not a multiple of 3");
  for (std::size_t i = 0; i < indices.size(); ++i)
    if (indices[i] >= vertices)
      throw std::invalid_argument("TerrainRenderer: index " + std::to_string(i) + " is " +
                                  std::to_string(indices[i]) + ", beyond the " + std::to_string(vertices) +
                                  " vertices");
}

glm::mat4 to_float(const glm::dmat4& m) { return glm::mat4(m); }

}  // namespace

// ---------------------------------------------------------------------------------------------

struct GpuMesh {
  GLuint vao_gpu = 0, vao_cpu = 0;  // vao_cpu reads z0 = z1 = the CPU-blended heights
  GLuint vbo = 0, vbo_z = 0, vbo_blend = 0, ibo = 0;
  glm::dvec3 origin{0.0};
  std::size_t vertices = 0, indices = 0;
  std::size_t vbo_capacity = 0, ibo_capacity = 0;  // in vertices / indices
  bool morphs = false;                             // some z_target differs from its z0
  std::vector<float> z0, z1;   // CPU copies: the CPU path blends them, new targets rewrite vbo_z
  std::vector<float> blended;  // scratch of the CPU path
  float blended_alpha = std::numeric_limits<float>::quiet_NaN();  // alpha in vbo_blend
  double z_lo = 0.0, z_hi = 0.0;  // world heights spanned (both ends of the morph)
};

struct TerrainRenderer::Impl {
  const detail::GlApi& gl;
  GLuint program = 0;
  GLint u_mvp = -1, u_alpha = -1, u_ramp = -1, u_light = -1, u_ambient = -1, u_flat = -1, u_color = -1;
  detail::OffscreenTarget target;
  std::map<std::uint32_t, GpuMesh> meshes;
  std::uint32_t next_id = 1;
  bool drawn = false;
  Camera last_camera;
  bool last_reverse_z = false;

  explicit Impl(const detail::GlApi& api) : gl(api) {}

  GpuMesh& mesh(MeshId id) {
    auto it = meshes.find(id.value);
    assert(it != meshes.end() && "TerrainRenderer: unknown or removed MeshId");
    return it->second;
  }
  const GpuMesh& mesh(MeshId id) const {
    auto it = meshes.find(id.value);
    assert(it != meshes.end() && "TerrainRenderer: unknown or removed MeshId");
    return it->second;
  }

  void build_program() {
    program = detail::build_program(gl, kVertexShader, kFragmentShader, "renderer");
    u_mvp = gl.GetUniformLocation(program, "u_mvp");
    u_alpha = gl.GetUniformLocation(program, "u_alpha");
    u_ramp = gl.GetUniformLocation(program, "u_ramp");
    u_light = gl.GetUniformLocation(program, "u_light");
    u_ambient = gl.GetUniformLocation(program, "u_ambient");
    u_flat = gl.GetUniformLocation(program, "u_flat");
    u_color = gl.GetUniformLocation(program, "u_color");
    detail::check_gl(gl, "renderer: building the shaders");
  }

  void ensure_framebuffer(int w, int h) { target.ensure(gl, w, h, "renderer"); }

  /// blend_buffer = 0: heights from vbo_z (GPU path); else both heights read it (CPU path).
  void set_attributes(GLuint vao, const GpuMesh& m, GLuint blend_buffer) {
    const auto offset = [](std::size_t bytes) { return reinterpret_cast<const void*>(bytes); };
    gl.BindVertexArray(vao);
    gl.BindBuffer(GL_ARRAY_BUFFER, m.vbo);
    gl.EnableVertexAttribArray(kXy);
    gl.VertexAttribPointer(kXy, 2, GL_FLOAT, GL_FALSE, kStride, offset(0));
    gl.EnableVertexAttribArray(kNormal);
    gl.VertexAttribPointer(kNormal, 3, GL_FLOAT, GL_FALSE, kStride, offset(2 * sizeof(float)));
    gl.EnableVertexAttribArray(kZ0);
    gl.EnableVertexAttribArray(kZ1);
    if (blend_buffer) {  // alpha = 0 then gives exactly the blended height
      gl.BindBuffer(GL_ARRAY_BUFFER, blend_buffer);
      gl.VertexAttribPointer(kZ0, 1, GL_FLOAT, GL_FALSE, sizeof(float), offset(0));
      gl.VertexAttribPointer(kZ1, 1, GL_FLOAT, GL_FALSE, sizeof(float), offset(0));
    } else {
      gl.BindBuffer(GL_ARRAY_BUFFER, m.vbo_z);
      gl.VertexAttribPointer(kZ0, 1, GL_FLOAT, GL_FALSE, kZStride, offset(0));
      gl.VertexAttribPointer(kZ1, 1, GL_FLOAT, GL_FALSE, kZStride, offset(sizeof(float)));
    }
    gl.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, m.ibo);
    gl.BindVertexArray(0);
  }

  /// Uploads m.z0, m.z1 to vbo_z (same vertex count as the buffer) and refreshes what depends on them.
  void write_heights(GpuMesh& m) {
    std::vector<float> zz(2 * m.vertices);
    m.morphs = false;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    for (std::size_t i = 0; i < m.vertices; ++i) {
      zz[2 * i] = m.z0[i], zz[2 * i + 1] = m.z1[i];
      m.morphs = m.morphs || m.z0[i] != m.z1[i];
      lo = std::min({lo, double(m.z0[i]), double(m.z1[i])});
      hi = std::max({hi, double(m.z0[i]), double(m.z1[i])});
    }
    m.z_lo = m.vertices ? m.origin.z + lo : m.origin.z;
    m.z_hi = m.vertices ? m.origin.z + hi : m.origin.z;
    m.blended_alpha = std::numeric_limits<float>::quiet_NaN();
    gl.BindBuffer(GL_ARRAY_BUFFER, m.vbo_z);
    if (!zz.empty()) gl.BufferSubData(GL_ARRAY_BUFFER, 0, GLsizeiptr(zz.size() * sizeof(float)), zz.data());
    detail::check_gl(gl, "renderer: uploading heights");
  }

  /// Writes an index list through GL_COPY_WRITE_BUFFER: that binding is not VAO state, so
  /// no vertex array has to be bound (or disturbed) to update a mesh's triangles.
  void write_indices(GpuMesh& m, std::span<const std::uint32_t> idx) {
    gl.BindBuffer(GL_COPY_WRITE_BUFFER, m.ibo);
    if (idx.size() > m.ibo_capacity)
      m.ibo_capacity = std::max<std::size_t>(idx.size(), m.ibo_capacity + m.ibo_capacity / 2);
    // New storage each time ("orphaning"): a frame still reading the old list never stalls this write.
    gl.BufferData(GL_COPY_WRITE_BUFFER, GLsizeiptr(m.ibo_capacity * 4), nullptr, GL_DYNAMIC_DRAW);
    if (!idx.empty()) gl.BufferSubData(GL_COPY_WRITE_BUFFER, 0, GLsizeiptr(idx.size() * 4), idx.data());
    gl.BindBuffer(GL_COPY_WRITE_BUFFER, 0);
    m.indices = idx.size();
  }

  void fill(GpuMesh& m, const DrawMesh& d) {
    const std::size_t n = d.vertex_count();
    const std::vector<float> computed = d.normals.empty() ? triangle_normals(d) : std::vector<float>();
    const std::vector<float>& nrm = d.normals.empty() ? computed : d.normals;
    std::vector<float> v(5 * n);
    m.z0.resize(n);
    m.z1.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      v[5 * i + 0] = d.xyz[3 * i];
      v[5 * i + 1] = d.xyz[3 * i + 1];
      v[5 * i + 2] = nrm[3 * i];
      v[5 * i + 3] = nrm[3 * i + 1];
      v[5 * i + 4] = nrm[3 * i + 2];
      m.z0[i] = d.xyz[3 * i + 2];
      m.z1[i] = d.z_target.empty() ? m.z0[i] : d.z_target[i];
    }
    m.origin = d.origin;
    m.vertices = n;
    if (n > m.vbo_capacity || n < m.vbo_capacity / 2) {  // (re)allocate both static buffers
      m.vbo_capacity = n;
      gl.BindBuffer(GL_ARRAY_BUFFER, m.vbo);
      gl.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(n * kStride), nullptr, GL_STATIC_DRAW);
      gl.BindBuffer(GL_ARRAY_BUFFER, m.vbo_z);
      gl.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(n * kZStride), nullptr, GL_STATIC_DRAW);
    }
    gl.BindBuffer(GL_ARRAY_BUFFER, m.vbo);
    if (n) gl.BufferSubData(GL_ARRAY_BUFFER, 0, GLsizeiptr(v.size() * sizeof(float)), v.data());
    write_heights(m);
    write_indices(m, d.indices);
    detail::check_gl(gl, "renderer: uploading a mesh");
  }

  /// CPU geomorph: blend the heights in float exactly as the shader does and upload them.
  std::size_t blend_on_cpu(GpuMesh& m, float alpha) {
    if (alpha == m.blended_alpha) return 0;
    m.blended.resize(m.vertices);
    const float a = alpha, b = 1.0f - alpha;
    const float* z0 = m.z0.data();
    const float* z1 = m.z1.data();
    float* out = m.blended.data();
    for (std::size_t i = 0; i < m.vertices; ++i) out[i] = b * z0[i] + a * z1[i];
    gl.BindBuffer(GL_ARRAY_BUFFER, m.vbo_blend);
    gl.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(m.vertices * sizeof(float)), out, GL_STREAM_DRAW);
    m.blended_alpha = alpha;
    return m.vertices * sizeof(float);
  }

  void free_mesh(GpuMesh& m) {
    const GLuint vaos[2] = {m.vao_gpu, m.vao_cpu};
    const GLuint bufs[4] = {m.vbo, m.vbo_z, m.vbo_blend, m.ibo};
    gl.DeleteVertexArrays(2, vaos);
    gl.DeleteBuffers(4, bufs);
  }
};

// ---------------------------------------------------------------------------------------------

TerrainRenderer::TerrainRenderer(GlContext& context, const RendererOptions& options)
    : ctx_(context), options_(options) {
  ctx_.make_current();
  impl_ = std::make_unique<Impl>(ctx_.api());
  impl_->build_program();
}

TerrainRenderer::~TerrainRenderer() {
  ctx_.make_current();
  const detail::GlApi& gl = impl_->gl;
  for (auto& [id, m] : impl_->meshes) impl_->free_mesh(m);
  impl_->target.release(gl);
  gl.DeleteProgram(impl_->program);
}

MeshId TerrainRenderer::upload(const DrawMesh& mesh) {
  validate(mesh);
  ctx_.make_current();
  const detail::GlApi& gl = impl_->gl;
  GpuMesh m;
  gl.GenVertexArrays(1, &m.vao_gpu);
  gl.GenVertexArrays(1, &m.vao_cpu);
  gl.GenBuffers(1, &m.vbo);
  gl.GenBuffers(1, &m.vbo_z);
  gl.GenBuffers(1, &m.vbo_blend);
  gl.GenBuffers(1, &m.ibo);
  try {
    impl_->fill(m, mesh);
  } catch (...) {
    impl_->free_mesh(m);
    throw;
  }
  impl_->set_attributes(m.vao_gpu, m, 0);
  impl_->set_attributes(m.vao_cpu, m, m.vbo_blend);
  const MeshId id{impl_->next_id++};
  impl_->meshes.emplace(id.value, std::move(m));
  return id;
}

void TerrainRenderer::replace(MeshId id, const DrawMesh& mesh) {
  validate(mesh);
  ctx_.make_current();
  impl_->fill(impl_->mesh(id), mesh);
}

void TerrainRenderer::update_indices(MeshId id, std::span<const std::uint32_t> indices) {
  GpuMesh& m = impl_->mesh(id);
  check_indices(indices, m.vertices);
  ctx_.make_current();
  impl_->write_indices(m, indices);
}

void TerrainRenderer::update_target_heights(MeshId id, std::span<const float> z_target) {
  GpuMesh& m = impl_->mesh(id);
  if (z_target.size() != m.vertices)
    throw std::invalid_argument("TerrainRenderer: " + std::to_string(z_target.size()) +
                                " target heights for " + std::to_string(m.vertices) + " vertices");
  if (!std::all_of(z_target.begin(), z_target.end(), [](float z) { return std::isfinite(z); }))
    throw std::invalid_argument("TerrainRenderer: a target height is not finite");
  ctx_.make_current();
  m.z1.assign(z_target.begin(), z_target.end());
  impl_->write_heights(m);
}

void TerrainRenderer::remove(MeshId id) {
  ctx_.make_current();
  GpuMesh& m = impl_->mesh(id);
  impl_->free_mesh(m);
  impl_->meshes.erase(id.value);
}

std::size_t TerrainRenderer::vertex_count(MeshId id) const { return impl_->mesh(id).vertices; }
std::size_t TerrainRenderer::triangle_count(MeshId id) const { return impl_->mesh(id).indices / 3; }

std::size_t TerrainRenderer::gpu_bytes() const {
  std::size_t b = 0;
  for (const auto& [id, m] : impl_->meshes)
    b += m.vbo_capacity * (kStride + kZStride) + m.ibo_capacity * 4 +
         (std::isnan(m.blended_alpha) ? 0 : m.vertices * 4);
  return b;
}

FrameStats TerrainRenderer::draw(const Camera& camera, std::span<const DrawItem> items) {
  ctx_.make_current();
  const detail::GlApi& gl = impl_->gl;
  FrameStats stats;
  const bool cpu = options_.geomorph == GeomorphPath::Cpu;

  // 1. CPU geomorph heights.
  auto t = Clock::now();
  if (cpu)
    for (const DrawItem& it : items) {
      assert(it.alpha >= 0.0f && it.alpha <= 1.0f && "DrawItem::alpha must be in [0, 1]");
      GpuMesh& m = impl_->mesh(it.mesh);
      if (m.morphs) stats.bytes_uploaded += impl_->blend_on_cpu(m, it.alpha);
    }
  stats.upload_ms = ms_since(t);

  // 2. The frame.
  t = Clock::now();
  impl_->ensure_framebuffer(camera.width_px, camera.height_px);
  const bool reverse = options_.reverse_z && ctx_.info().clip_control;
  gl.BindFramebuffer(GL_FRAMEBUFFER, impl_->target.fbo);
  gl.Viewport(0, 0, camera.width_px, camera.height_px);
  if (ctx_.info().clip_control)
    gl.ClipControl(GL_LOWER_LEFT, reverse ? GL_ZERO_TO_ONE : GL_NEGATIVE_ONE_TO_ONE);
  gl.ClearColor(options_.sky_color.r, options_.sky_color.g, options_.sky_color.b, 1.0f);
  gl.ClearDepth(reverse ? 0.0 : 1.0);
  gl.DepthMask(GL_TRUE);
  gl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  gl.Enable(GL_DEPTH_TEST);
  gl.DepthFunc(reverse ? GL_GREATER : GL_LESS);
  gl.Disable(GL_CULL_FACE);
  gl.Disable(GL_BLEND);
  gl.UseProgram(impl_->program);

  const glm::dvec3 light = glm::normalize(options_.light_direction);
  gl.Uniform3f(impl_->u_light, float(light.x), float(light.y), float(light.z));
  gl.Uniform1f(impl_->u_ambient, options_.ambient);
  gl.Uniform3f(impl_->u_color, options_.wire_color.r, options_.wire_color.g, options_.wire_color.b);
  double ramp_lo = options_.ramp_low, ramp_hi = options_.ramp_high;
  if (!(ramp_lo < ramp_hi)) {
    ramp_lo = std::numeric_limits<double>::infinity(), ramp_hi = -ramp_lo;
    for (const auto& [id, m] : impl_->meshes)
      ramp_lo = std::min(ramp_lo, m.z_lo), ramp_hi = std::max(ramp_hi, m.z_hi);
    if (!(ramp_lo < ramp_hi)) ramp_lo = 0.0, ramp_hi = 1.0;
  }

  const glm::dmat4 pv =
      (reverse ? reverse_z_projection_matrix(camera) : projection_matrix(camera)) * view_matrix(camera);
  for (int pass = 0; pass < (options_.wireframe ? 2 : 1); ++pass) {
    const bool lines = pass == 1;
    if (options_.wireframe && !lines) {  // push the surface back so that its edges win
      gl.Enable(GL_POLYGON_OFFSET_FILL);
      gl.PolygonOffset(reverse ? -1.0f : 1.0f, reverse ? -1.0f : 1.0f);
    }
    if (lines) {
      gl.Disable(GL_POLYGON_OFFSET_FILL);
      gl.PolygonMode(GL_FRONT_AND_BACK, GL_LINE);
      gl.DepthFunc(reverse ? GL_GEQUAL : GL_LEQUAL);
    }
    gl.Uniform1f(impl_->u_flat, lines ? 1.0f : 0.0f);
    for (const DrawItem& it : items) {
      assert(it.alpha >= 0.0f && it.alpha <= 1.0f && "DrawItem::alpha must be in [0, 1]");
      const GpuMesh& m = impl_->mesh(it.mesh);
      if (m.indices == 0) continue;
      const bool blended = cpu && m.morphs;
      const glm::dmat4 model = glm::translate(glm::dmat4(1.0), m.origin);
      const glm::mat4 mvp = to_float(pv * model);
      gl.UniformMatrix4fv(impl_->u_mvp, 1, GL_FALSE, &mvp[0][0]);
      gl.Uniform1f(impl_->u_alpha, blended ? 0.0f : it.alpha);
      // ramp = (z + origin.z - lo) / (hi - lo)
      const double scale = 1.0 / (ramp_hi - ramp_lo);
      gl.Uniform2f(impl_->u_ramp, float(scale), float((m.origin.z - ramp_lo) * scale));
      gl.BindVertexArray(blended ? m.vao_cpu : m.vao_gpu);
      gl.DrawElements(GL_TRIANGLES, GLsizei(m.indices), GL_UNSIGNED_INT, nullptr);
      if (!lines) {
        ++stats.meshes;
        stats.triangles += m.indices / 3;
      }
    }
  }
  gl.PolygonMode(GL_FRONT_AND_BACK, GL_FILL);
  gl.Disable(GL_POLYGON_OFFSET_FILL);
  gl.BindVertexArray(0);
  if (options_.finish) gl.Finish();
  detail::check_gl(gl, "renderer: drawing a frame");
  stats.draw_ms = ms_since(t);

  impl_->drawn = true;
  impl_->last_camera = camera;
  impl_->last_reverse_z = reverse;
  return stats;
}

Image TerrainRenderer::read_color() const {
  assert(impl_->drawn && "TerrainRenderer::read_color before the first draw()");
  ctx_.make_current();
  return impl_->target.read_rgb(impl_->gl, "renderer");
}

Image TerrainRenderer::read_window_color(bool blit) {
  assert(impl_->drawn && "TerrainRenderer::read_window_color before the first draw()");
  ctx_.make_current();
  const detail::GlApi& gl = impl_->gl;
  const int w = ctx_.framebuffer_width(), h = ctx_.framebuffer_height();
  if (blit) {
    gl.BindFramebuffer(GL_READ_FRAMEBUFFER, impl_->target.fbo);
    gl.BindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
    const bool same = w == impl_->target.width && h == impl_->target.height;
    gl.BlitFramebuffer(0, 0, impl_->target.width, impl_->target.height, 0, 0, w, h, GL_COLOR_BUFFER_BIT,
                       same ? GL_NEAREST : GL_LINEAR);
  }
  // The default framebuffer keeps its own read buffer (GL_BACK, or GL_FRONT when single-buffered).
  gl.BindFramebuffer(GL_READ_FRAMEBUFFER, 0);
  std::vector<std::uint8_t> rgba(std::size_t(w) * h * 4);
  gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
  gl.ReadPixels(0, 0, w, h, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
  detail::check_gl(gl, "renderer: reading the default framebuffer back");
  Image img;
  img.width = w;
  img.height = h;
  img.rgb.resize(std::size_t(w) * h * 3);
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* src = rgba.data() + std::size_t(h - 1 - y) * w * 4;
    std::uint8_t* dst = img.pixel(0, y);
    for (int x = 0; x < w; ++x)
      dst[3 * x] = src[4 * x], dst[3 * x + 1] = src[4 * x + 1], dst[3 * x + 2] = src[4 * x + 2];
  }
  return img;
}

std::vector<DepthSample> TerrainRenderer::read_depth(std::span<const glm::ivec2> pixels) const {
  assert(impl_->drawn && "TerrainRenderer::read_depth before the first draw()");
  std::vector<DepthSample> out(pixels.size());
  if (pixels.empty()) return out;
  const int w = impl_->target.width, h = impl_->target.height;
  glm::ivec2 lo = pixels[0], hi = pixels[0];
  for (const glm::ivec2& p : pixels) {
    assert(p.x >= 0 && p.y >= 0 && p.x < w && p.y < h && "read_depth: pixel outside the frame");
    lo = glm::min(lo, p), hi = glm::max(hi, p);
  }
  (void)w;
  ctx_.make_current();
  const detail::GlApi& gl = impl_->gl;
  // Image rows [lo.y, hi.y] are GL rows [h-1-hi.y, h-1-lo.y].
  const int rw = hi.x - lo.x + 1, rh = hi.y - lo.y + 1, gl_y0 = h - 1 - hi.y;
  std::vector<float> depth(std::size_t(rw) * rh);
  gl.BindFramebuffer(GL_READ_FRAMEBUFFER, impl_->target.fbo);
  gl.PixelStorei(GL_PACK_ALIGNMENT, 4);
  gl.ReadPixels(lo.x, gl_y0, rw, rh, GL_DEPTH_COMPONENT, GL_FLOAT, depth.data());
  detail::check_gl(gl, "renderer: reading depth back");

  const Camera& cam = impl_->last_camera;
  const bool reverse = impl_->last_reverse_z;
  const glm::dmat4 inv_proj =
      glm::inverse(reverse ? reverse_z_projection_matrix(cam) : projection_matrix(cam));
  const glm::dmat4 inv_view = glm::inverse(view_matrix(cam));
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const glm::ivec2 p = pixels[i];
    const double d = depth[std::size_t(h - 1 - p.y - gl_y0) * rw + (p.x - lo.x)];
    DepthSample& s = out[i];
    s.pixel = p;
    s.window_depth = d;
    s.hit = reverse ? d > 0.0 : d < 1.0;
    if (!s.hit) {
      s.eye_depth = s.distance = std::numeric_limits<double>::infinity();
      s.world = glm::dvec3(std::numeric_limits<double>::quiet_NaN());
      continue;
    }
    const glm::dvec4 ndc(2.0 * (p.x + 0.5) / cam.width_px - 1.0, 1.0 - 2.0 * (p.y + 0.5) / cam.height_px,
                         reverse ? d : 2.0 * d - 1.0, 1.0);
    glm::dvec4 eye = inv_proj * ndc;
    eye /= eye.w;
    s.eye_depth = -eye.z;
    s.distance = glm::length(glm::dvec3(eye));
    s.world = glm::dvec3(inv_view * glm::dvec4(glm::dvec3(eye), 1.0));
  }
  return out;
}

FrameTarget TerrainRenderer::bind_frame() {
  assert(impl_->drawn && "TerrainRenderer::bind_frame before the first draw()");
  ctx_.make_current();
  const detail::GlApi& gl = impl_->gl;
  const Camera& cam = impl_->last_camera;
  const bool reverse = impl_->last_reverse_z;
  gl.BindFramebuffer(GL_FRAMEBUFFER, impl_->target.fbo);
  gl.Viewport(0, 0, cam.width_px, cam.height_px);
  if (ctx_.info().clip_control)
    gl.ClipControl(GL_LOWER_LEFT, reverse ? GL_ZERO_TO_ONE : GL_NEGATIVE_ONE_TO_ONE);
  detail::check_gl(gl, "renderer: binding the frame");
  return {cam, reverse,
          (reverse ? reverse_z_projection_matrix(cam) : projection_matrix(cam)) * view_matrix(cam),
          options_.light_direction, options_.ambient};
}

void TerrainRenderer::present(bool swap) {
  assert(impl_->drawn && "TerrainRenderer::present before the first draw()");
  ctx_.make_current();
  const detail::GlApi& gl = impl_->gl;
  const int w = ctx_.framebuffer_width(), h = ctx_.framebuffer_height();
  gl.BindFramebuffer(GL_READ_FRAMEBUFFER, impl_->target.fbo);
  gl.BindFramebuffer(GL_DRAW_FRAMEBUFFER, 0);
  const bool same = w == impl_->target.width && h == impl_->target.height;
  gl.BlitFramebuffer(0, 0, impl_->target.width, impl_->target.height, 0, 0, w, h, GL_COLOR_BUFFER_BIT,
                     same ? GL_NEAREST : GL_LINEAR);
  detail::check_gl(gl, "renderer: presenting the frame");
  if (swap) ctx_.swap_buffers();
}

}  // namespace terralod::render
