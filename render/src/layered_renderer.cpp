// GPU combination of texture layers (dynamic-3d-maps-texture-layers.txt section 6): shaders
// generated per layer configuration, one pass by multitexturing or several with GL blending.
#include "terralod/render/layered_renderer.hpp"

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <cstring>
#include <glm/gtc/matrix_transform.hpp>
#include <map>
#include <optional>
#include <stdexcept>
#include <string>

#include "gl_api.hpp"

// OSMesa's loader, declared here: <GL/osmesa.h> pulls in <GL/gl.h>, which must not meet
// <GL/glcorearb.h> (see gl_api.hpp).
extern "C" {
typedef void (*OSMESAproc)();
OSMESAproc OSMesaGetProcAddress(const char* funcName);
}

namespace terralod::render {
namespace {

using Clock = std::chrono::steady_clock;
constexpr int kMaxUnits = 16;  // samplers a generated program may declare

// Texture and blending entry points the shared table (gl_api.hpp) does not load.
struct TexApi {
  PFNGLGENTEXTURESPROC GenTextures = nullptr;
  PFNGLDELETETEXTURESPROC DeleteTextures = nullptr;
  PFNGLBINDTEXTUREPROC BindTexture = nullptr;
  PFNGLACTIVETEXTUREPROC ActiveTexture = nullptr;
  PFNGLTEXIMAGE2DPROC TexImage2D = nullptr;
  PFNGLTEXPARAMETERIPROC TexParameteri = nullptr;
  PFNGLTEXPARAMETERFVPROC TexParameterfv = nullptr;
  PFNGLUNIFORM1IPROC Uniform1i = nullptr;
  PFNGLUNIFORM4FPROC Uniform4f = nullptr;
  PFNGLBLENDFUNCPROC BlendFunc = nullptr;
  PFNGLBLENDEQUATIONPROC BlendEquation = nullptr;

  void load(const GlContext& ctx) {
    void* (*get)(const char*) = nullptr;
    if (ctx.info().backend == "osmesa")
      get = [](const char* n) { return reinterpret_cast<void*>(OSMesaGetProcAddress(n)); };
    else
      get = [](const char* n) { return reinterpret_cast<void*>(glfwGetProcAddress(n)); };
    std::string missing;
    auto one = [&](auto& fn, const char* name) {
      fn = reinterpret_cast<std::remove_reference_t<decltype(fn)>>(get(name));
      if (!fn) missing += std::string(missing.empty() ? "" : ", ") + name;
    };
    one(GenTextures, "glGenTextures");
    one(DeleteTextures, "glDeleteTextures");
    one(BindTexture, "glBindTexture");
    one(ActiveTexture, "glActiveTexture");
    one(TexImage2D, "glTexImage2D");
    one(TexParameteri, "glTexParameteri");
    one(TexParameterfv, "glTexParameterfv");
    one(Uniform1i, "glUniform1i");
    one(Uniform4f, "glUniform4f");
    one(BlendFunc, "glBlendFunc");
    one(BlendEquation, "glBlendEquation");
    if (!missing.empty()) throw RenderError("layered renderer: missing GL entry points: " + missing);
  }
};

const char* kVertexShader = R"(#version 330 core
layout(location = 0) in vec3 a_xyz;
layout(location = 1) in vec3 a_normal;
uniform mat4 u_mvp;
out vec2 v_rel;      // mesh-relative x, y (metres)
out vec3 v_normal;
invariant gl_Position;  // every pass lands on the same depth
void main() {
  v_rel = a_xyz.xy;
  v_normal = a_normal;
  gl_Position = u_mvp * vec4(a_xyz, 1.0);
}
)";

// What one generated program does.
struct PassSpec {
  enum Kind : std::uint8_t { Single, Base, Layer, Light } kind = Single;
  int layer = -1;  // Kind::Layer: the style index
  std::string signature;
};

// One sampled layer inside a program.
struct SampledLayer {
  int style = -1;
  int unit = -1, next_unit = -1;  // next_unit: sequence's second key frame
};

struct Program {
  GLuint id = 0;
  GLint u_mvp = -1, u_base = -1, u_light = -1, u_ambient = -1, u_lens_uv = -1;
  std::vector<SampledLayer> sampled;
  std::vector<GLint> u_uv, u_w, u_mix;  // per sampled layer
  int lens_unit = -1;
};

struct GpuMesh {
  GLuint vao = 0, vbo = 0, ibo = 0;
  glm::dvec3 origin{0.0};
  std::size_t indices = 0;
};

struct GpuTexture {
  GLuint id = 0;
  std::size_t bytes = 0;
};

struct Resident {
  TextureId id;
  std::uint64_t last_frame = 0;
};

}  // namespace

struct LayeredRenderer::Impl {
  const detail::GlApi& gl;
  TexApi tx;
  int gl_units = 16;
  detail::OffscreenTarget target;
  std::optional<Camera> last_camera;  // of the last draw(), for bind_frame()
  std::map<std::uint32_t, GpuMesh> meshes;
  std::uint32_t next_mesh = 1;
  std::map<std::uint32_t, GpuTexture> textures;
  std::uint32_t next_texture = 1;
  GLuint empty_texture = 0;  // 1x1 transparent, for absent layers
  GLuint lens_texture = 0;
  std::size_t lens_bytes = 0;
  std::map<TextureKey, Resident> resident;
  std::map<std::uint32_t, TextureKey> key_of;
  std::uint64_t frame = 0;
  std::size_t texture_bytes = 0, uploads_total = 0;
  std::size_t pending_uploads = 0, pending_bytes = 0;
  std::map<std::string, Program> programs;
  bool drawn = false;

  explicit Impl(const detail::GlApi& api) : gl(api) {}

  GLuint make_texture(const RgbaImage& img, bool border) {
    if (img.width < 1 || img.height < 1 || img.rgba.size() != std::size_t(img.width) * img.height * 4)
      throw std::invalid_argument("LayeredRenderer: a " + std::to_string(img.width) + " x " +
                                  std::to_string(img.height) + " texture with " +
                                  std::to_string(img.rgba.size()) + " bytes");
    GLuint t = 0;
    tx.GenTextures(1, &t);
    tx.BindTexture(GL_TEXTURE_2D, t);
    gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    tx.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, img.width, img.height, 0, GL_RGBA, GL_UNSIGNED_BYTE,
                  img.rgba.data());
    tx.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, 0);
    const GLint wrap = border ? GL_CLAMP_TO_BORDER : GL_CLAMP_TO_EDGE;
    tx.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, wrap);
    tx.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, wrap);
    const float transparent[4] = {0, 0, 0, 0};
    tx.TexParameterfv(GL_TEXTURE_2D, GL_TEXTURE_BORDER_COLOR, transparent);
    detail::check_gl(gl, "layered renderer: uploading a texture");
    return t;
  }

  void set_filter(GLuint t, bool linear) {
    tx.BindTexture(GL_TEXTURE_2D, t);
    const GLint f = linear ? GL_LINEAR : GL_NEAREST;
    tx.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, f);
    tx.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, f);
  }

  void ensure_framebuffer(int w, int h) { target.ensure(gl, w, h, "layered renderer"); }

  // Layers a colour layer samples: itself and its mask layer.
  static bool sampled_by_any(std::span<const LayerStyle> st, int i) {
    if (st[std::size_t(i)].enabled && !st[std::size_t(i)].mask_only) return true;
    for (const LayerStyle& s : st)
      if (s.enabled && !s.mask_only && s.mask == MaskSource::Layer && s.mask_layer == i) return true;
    return false;
  }

  // Fragment shader + sampler plan for a pass over colour layers `colour` (style indices).
  Program& program_for(std::span<const LayerStyle> st, const std::vector<bool>& seq, const Lens& lens,
                       const PassSpec& pass, const LayerStackOptions& stack) {
    // Which layers this pass samples.
    std::vector<int> colour, sampled;
    if (pass.kind == PassSpec::Single) {
      for (int i = 0; i < int(st.size()); ++i)
        if (st[std::size_t(i)].enabled && !st[std::size_t(i)].mask_only) colour.push_back(i);
      for (int i = 0; i < int(st.size()); ++i)
        if (sampled_by_any(st, i)) sampled.push_back(i);
    } else if (pass.kind == PassSpec::Layer) {
      colour.push_back(pass.layer);
      sampled.push_back(pass.layer);
      const LayerStyle& s = st[std::size_t(pass.layer)];
      if (s.mask == MaskSource::Layer) sampled.push_back(s.mask_layer);
    }
    bool uses_lens = false;
    for (int i : colour) uses_lens = uses_lens || st[std::size_t(i)].mask == MaskSource::Lens;
    uses_lens = uses_lens && lens.enabled;
    const bool lit = stack.lighting && !decal_mode(st);
    // Signature: everything that changes the generated code.
    std::string sig = std::to_string(int(pass.kind)) + (lit ? "L" : "U") + (uses_lens ? "Z" : "-");
    // (appends, not "s" + std::to_string(i): GCC 12 warns wrongly with -Wrestrict on that form)
    for (int i : sampled) {
      sig += 's';
      sig += std::to_string(i);
      if (seq[std::size_t(i)]) sig += 'q';
    }
    for (int i : colour) {
      const LayerStyle& s = st[std::size_t(i)];
      sig += 'c';
      sig += std::to_string(i);
      sig += 'o';
      sig += std::to_string(int(s.op));
      sig += 'm';
      sig += std::to_string(int(s.mask));
      sig += ',';
      sig += std::to_string(s.mask_layer);
      if (s.invert_mask) sig += 'i';
    }
    auto found = programs.find(sig);
    if (found != programs.end()) return found->second;

    Program p;
    std::string fs =
        "#version 330 core\nin vec2 v_rel;\nin vec3 v_normal;\nout vec4 o_color;\n"
        "uniform vec3 u_base;\nuniform vec3 u_light;\nuniform float u_ambient;\nuniform vec4 u_lens_uv;\n";
    int unit = 0;
    std::string body;
    for (int i : sampled) {
      SampledLayer sl{i, unit++, -1};
      if (seq[std::size_t(i)]) sl.next_unit = unit++;
      const std::string n = std::to_string(i);
      fs += "uniform sampler2D u_t" + n + ";\nuniform vec4 u_uv" + n + ";\nuniform float u_w" + n + ";\n";
      body += "  vec2 uv" + n + " = vec2((v_rel.x + u_uv" + n + ".x) * u_uv" + n + ".z, (u_uv" + n +
              ".y - v_rel.y) * u_uv" + n + ".w);\n  vec4 t" + n + " = texture(u_t" + n + ", uv" + n + ");\n";
      if (sl.next_unit >= 0) {
        fs += "uniform sampler2D u_n" + n + ";\nuniform float u_mix" + n + ";\n";
        body += "  t" + n + " = mix(t" + n + ", texture(u_n" + n + ", uv" + n + "), u_mix" + n + ");\n";
      }
      p.sampled.push_back(sl);
    }
    if (uses_lens) {
      p.lens_unit = unit++;
      fs += "uniform sampler2D u_lens;\n";
      body +=
          "  float lens = texture(u_lens, vec2((v_rel.x + u_lens_uv.x) * u_lens_uv.z, (u_lens_uv.y - "
          "v_rel.y) * "
          "u_lens_uv.w)).a;\n";
    }
    assert(unit <= kMaxUnits);
    fs += "void main() {\n" + body;
    fs += "  float light = u_ambient + (1.0 - u_ambient) * max(dot(normalize(v_normal), u_light), 0.0);\n";
    auto weight = [&](int i) {  // s = weight * alpha * mask
      const LayerStyle& s = st[std::size_t(i)];
      const std::string n = std::to_string(i);
      std::string m = "1.0";
      if (s.mask == MaskSource::Layer) m = "t" + std::to_string(s.mask_layer) + ".a";
      if (s.mask == MaskSource::Lens) m = uses_lens ? "lens" : "0.0";
      if (s.mask != MaskSource::None && s.invert_mask) m = "(1.0 - " + m + ")";
      return "u_w" + n + " * t" + n + ".a * " + m;
    };
    if (pass.kind == PassSpec::Single) {
      fs += "  vec3 c = u_base;\n";
      for (int i : colour) {
        const std::string n = std::to_string(i);
        fs += "  { float s = " + weight(i) + ";\n";
        switch (st[std::size_t(i)].op) {
          case LayerOp::Blend:
            fs += "    c = c + (t" + n + ".rgb - c) * s;\n";
            break;
          case LayerOp::Add:
            fs += "    c = c + s * t" + n + ".rgb;\n";
            break;
          case LayerOp::Subtract:
            fs += "    c = c - s * t" + n + ".rgb;\n";
            break;
          case LayerOp::Multiply:
            fs += "    c = c * (vec3(1.0) + (t" + n + ".rgb - vec3(1.0)) * s);\n";
            break;
        }
        fs += "    c = clamp(c, 0.0, 1.0); }\n";
      }
      if (lit) fs += "  c = clamp(c * light, 0.0, 1.0);\n";
      fs += "  o_color = vec4(c, 1.0);\n";
    } else if (pass.kind == PassSpec::Base) {
      fs += "  o_color = vec4(u_base, 1.0);\n";
    } else if (pass.kind == PassSpec::Light) {
      fs += "  o_color = vec4(vec3(light), 1.0);\n";
    } else {
      const int i = pass.layer;
      const std::string n = std::to_string(i);
      fs += "  float s = " + weight(i) + ";\n";
      switch (st[std::size_t(i)].op) {
        case LayerOp::Blend:
          fs += "  o_color = vec4(t" + n + ".rgb, s);\n";
          break;
        case LayerOp::Add:
        case LayerOp::Subtract:
          fs += "  o_color = vec4(s * t" + n + ".rgb, 1.0);\n";
          break;
        case LayerOp::Multiply:
          fs += "  o_color = vec4(vec3(1.0) + (t" + n + ".rgb - vec3(1.0)) * s, 1.0);\n";
          break;
      }
    }
    fs += "}\n";
    (void)stack;

    p.id = detail::build_program(gl, kVertexShader, fs, "layered renderer (generated program)");
    gl.UseProgram(p.id);
    p.u_mvp = gl.GetUniformLocation(p.id, "u_mvp");
    p.u_base = gl.GetUniformLocation(p.id, "u_base");
    p.u_light = gl.GetUniformLocation(p.id, "u_light");
    p.u_ambient = gl.GetUniformLocation(p.id, "u_ambient");
    p.u_lens_uv = gl.GetUniformLocation(p.id, "u_lens_uv");
    for (const SampledLayer& sl : p.sampled) {
      const std::string n = std::to_string(sl.style);
      tx.Uniform1i(gl.GetUniformLocation(p.id, ("u_t" + n).c_str()), sl.unit);
      if (sl.next_unit >= 0) tx.Uniform1i(gl.GetUniformLocation(p.id, ("u_n" + n).c_str()), sl.next_unit);
      p.u_uv.push_back(gl.GetUniformLocation(p.id, ("u_uv" + n).c_str()));
      p.u_w.push_back(gl.GetUniformLocation(p.id, ("u_w" + n).c_str()));
      p.u_mix.push_back(gl.GetUniformLocation(p.id, ("u_mix" + n).c_str()));
    }
    if (p.lens_unit >= 0) tx.Uniform1i(gl.GetUniformLocation(p.id, "u_lens"), p.lens_unit);
    detail::check_gl(gl, "layered renderer: building a layer program");
    return programs.emplace(sig, std::move(p)).first->second;
  }

  GLuint gl_texture(TextureId id) const {
    if (id.value == 0) return empty_texture;
    auto it = textures.find(id.value);
    assert(it != textures.end() && "LayeredRenderer: unknown or removed TextureId");
    return it->second.id;
  }

  void free_texture(std::uint32_t v) {
    auto it = textures.find(v);
    assert(it != textures.end());
    tx.DeleteTextures(1, &it->second.id);
    texture_bytes -= it->second.bytes;
    textures.erase(it);
    auto k = key_of.find(v);
    if (k != key_of.end()) {
      resident.erase(k->second);
      key_of.erase(k);
    }
  }
};

// ---------------------------------------------------------------------------------------------

LayeredRenderer::LayeredRenderer(GlContext& context, const LayeredRendererOptions& options)
    : ctx_(context), options_(options) {
  ctx_.make_current();
  impl_ = std::make_unique<Impl>(ctx_.api());
  impl_->tx.load(ctx_);
  GLint units = 0;
  impl_->gl.GetIntegerv(GL_MAX_TEXTURE_IMAGE_UNITS, &units);
  impl_->gl_units = std::max(1, int(units));
  RgbaImage empty(1, 1);
  impl_->empty_texture = impl_->make_texture(empty, false);
  impl_->set_filter(impl_->empty_texture, false);
}

LayeredRenderer::~LayeredRenderer() {
  ctx_.make_current();
  const detail::GlApi& gl = impl_->gl;
  for (auto& [id, m] : impl_->meshes) {
    gl.DeleteVertexArrays(1, &m.vao);
    const GLuint b[2] = {m.vbo, m.ibo};
    gl.DeleteBuffers(2, b);
  }
  for (auto& [id, t] : impl_->textures) impl_->tx.DeleteTextures(1, &t.id);
  impl_->tx.DeleteTextures(1, &impl_->empty_texture);
  if (impl_->lens_texture) impl_->tx.DeleteTextures(1, &impl_->lens_texture);
  for (auto& [sig, p] : impl_->programs) gl.DeleteProgram(p.id);
  impl_->target.release(gl);
}

int LayeredRenderer::texture_units() const {
  int u = std::min(impl_->gl_units, kMaxUnits);
  if (options_.max_texture_units > 0) u = std::min(u, options_.max_texture_units);
  return u;
}

int LayeredRenderer::passes_for(std::span<const LayerStyle> st, const Lens& lens, bool has_sequences) const {
  int units = 0, colour = 0;
  bool lens_used = false;
  for (int i = 0; i < int(st.size()); ++i) {
    if (Impl::sampled_by_any(st, i)) units += has_sequences ? 2 : 1;
    if (st[std::size_t(i)].enabled && !st[std::size_t(i)].mask_only) {
      ++colour;
      lens_used = lens_used || st[std::size_t(i)].mask == MaskSource::Lens;
    }
  }
  if (lens_used && lens.enabled) ++units;
  if (units <= texture_units()) return 1;
  const bool lit = options_.stack.lighting && !decal_mode(st);
  return 1 + colour + (lit ? 1 : 0);
}

MeshId LayeredRenderer::upload(const DrawMesh& d) {
  validate(d);
  ctx_.make_current();
  const detail::GlApi& gl = impl_->gl;
  const std::vector<float> computed = d.normals.empty() ? triangle_normals(d) : std::vector<float>();
  const std::vector<float>& nrm = d.normals.empty() ? computed : d.normals;
  std::vector<float> v(6 * d.vertex_count());
  for (std::size_t i = 0; i < d.vertex_count(); ++i)
    for (int k = 0; k < 3; ++k) v[6 * i + k] = d.xyz[3 * i + k], v[6 * i + 3 + k] = nrm[3 * i + k];
  GpuMesh m;
  m.origin = d.origin;
  m.indices = d.indices.size();
  gl.GenVertexArrays(1, &m.vao);
  gl.GenBuffers(1, &m.vbo);
  gl.GenBuffers(1, &m.ibo);
  gl.BindVertexArray(m.vao);
  gl.BindBuffer(GL_ARRAY_BUFFER, m.vbo);
  gl.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(v.size() * sizeof(float)), v.data(), GL_STATIC_DRAW);
  gl.EnableVertexAttribArray(0);
  gl.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), nullptr);
  gl.EnableVertexAttribArray(1);
  gl.VertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float),
                         reinterpret_cast<const void*>(3 * sizeof(float)));
  gl.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, m.ibo);
  gl.BufferData(GL_ELEMENT_ARRAY_BUFFER, GLsizeiptr(d.indices.size() * 4), d.indices.data(), GL_STATIC_DRAW);
  gl.BindVertexArray(0);
  detail::check_gl(gl, "layered renderer: uploading a mesh");
  const MeshId id{impl_->next_mesh++};
  impl_->meshes.emplace(id.value, m);
  return id;
}

void LayeredRenderer::remove(MeshId id) {
  ctx_.make_current();
  auto it = impl_->meshes.find(id.value);
  assert(it != impl_->meshes.end() && "LayeredRenderer: unknown or removed MeshId");
  impl_->gl.DeleteVertexArrays(1, &it->second.vao);
  const GLuint b[2] = {it->second.vbo, it->second.ibo};
  impl_->gl.DeleteBuffers(2, b);
  impl_->meshes.erase(it);
}

TextureId LayeredRenderer::upload_texture(const RgbaImage& image) {
  ctx_.make_current();
  GpuTexture t;
  t.id = impl_->make_texture(image, false);
  impl_->set_filter(t.id, options_.linear_filter);
  t.bytes = image.rgba.size();
  impl_->texture_bytes += t.bytes;
  ++impl_->uploads_total;
  ++impl_->pending_uploads;
  impl_->pending_bytes += t.bytes;
  const TextureId id{impl_->next_texture++};
  impl_->textures.emplace(id.value, t);
  return id;
}

void LayeredRenderer::remove_texture(TextureId id) {
  ctx_.make_current();
  impl_->free_texture(id.value);
}

TextureId LayeredRenderer::texture_for(const TextureKey& key, const RgbaImage& image) {
  auto it = impl_->resident.find(key);
  if (it != impl_->resident.end()) {
    it->second.last_frame = impl_->frame;
    return it->second.id;
  }
  const TextureId id = upload_texture(image);
  impl_->resident[key] = Resident{id, impl_->frame};
  impl_->key_of[id.value] = key;
  return id;
}

bool LayeredRenderer::has_texture(const TextureKey& key) const { return impl_->resident.count(key) != 0; }

void LayeredRenderer::set_lens_texture(const RgbaImage& image) {
  ctx_.make_current();
  if (impl_->lens_texture) impl_->tx.DeleteTextures(1, &impl_->lens_texture);
  impl_->lens_texture = impl_->make_texture(image, /*border=*/true);
  impl_->set_filter(impl_->lens_texture, options_.linear_filter);
  impl_->lens_bytes = image.rgba.size();
  ++impl_->uploads_total;
  ++impl_->pending_uploads;
  impl_->pending_bytes += image.rgba.size();
}

std::size_t LayeredRenderer::texture_bytes() const { return impl_->texture_bytes + impl_->lens_bytes; }
std::size_t LayeredRenderer::textures_uploaded_total() const { return impl_->uploads_total; }

LayeredFrameStats LayeredRenderer::draw(const Camera& camera, std::span<const LayerStyle> st,
                                        const Lens& lens, std::span<const LayeredItem> items) {
  const auto t0 = Clock::now();
  ctx_.make_current();
  Impl& im = *impl_;
  const detail::GlApi& gl = im.gl;
  LayeredFrameStats stats;
  for (const LayeredItem& it : items)
    if (it.layers.size() != st.size())
      throw std::invalid_argument("LayeredRenderer: an item binds " + std::to_string(it.layers.size()) +
                                  " layers for " + std::to_string(st.size()) + " styles");
  assert(!lens.enabled || im.lens_texture);
  ++im.frame;
  // Sequence layers: any item binds a next key frame.
  std::vector<bool> seq(st.size(), false);
  for (const LayeredItem& it : items)
    for (std::size_t i = 0; i < st.size(); ++i) seq[i] = seq[i] || it.layers[i].next.value != 0;
  const bool any_seq = std::find(seq.begin(), seq.end(), true) != seq.end();
  const int passes = passes_for(st, lens, any_seq);

  im.ensure_framebuffer(camera.width_px, camera.height_px);
  im.last_camera = camera;
  gl.BindFramebuffer(GL_FRAMEBUFFER, im.target.fbo);
  gl.Viewport(0, 0, camera.width_px, camera.height_px);
  gl.ClearColor(options_.sky_color.r, options_.sky_color.g, options_.sky_color.b, 1.0f);
  gl.ClearDepth(1.0);
  gl.Clear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
  gl.Enable(GL_DEPTH_TEST);
  gl.Disable(GL_CULL_FACE);

  // Draw order: grouped by the bound textures.
  std::vector<std::size_t> order(items.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  auto tex_key = [&](std::size_t i) {
    std::vector<std::uint32_t> k;
    for (const LayerBinding& b : items[i].layers) k.push_back(b.texture.value), k.push_back(b.next.value);
    return k;
  };
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return tex_key(a) < tex_key(b); });

  const glm::dmat4 pv = projection_matrix(camera) * view_matrix(camera);
  const glm::dvec3 light = glm::normalize(options_.light_direction);

  std::vector<PassSpec> plan;
  if (passes == 1) {
    plan.push_back({PassSpec::Single, -1, ""});
  } else {
    plan.push_back({PassSpec::Base, -1, ""});
    for (int i = 0; i < int(st.size()); ++i)
      if (st[std::size_t(i)].enabled && !st[std::size_t(i)].mask_only)
        plan.push_back({PassSpec::Layer, i, ""});
    if (options_.stack.lighting && !decal_mode(st)) plan.push_back({PassSpec::Light, -1, ""});
  }
  stats.passes = int(plan.size());

  for (std::size_t pi = 0; pi < plan.size(); ++pi) {
    const PassSpec& pass = plan[pi];
    Program& p = im.program_for(st, seq, lens, pass, options_.stack);
    gl.UseProgram(p.id);
    gl.DepthFunc(pi == 0 ? GL_LESS : GL_LEQUAL);
    gl.DepthMask(pi == 0 ? GL_TRUE : GL_FALSE);
    if (pi == 0) {
      gl.Disable(GL_BLEND);
    } else {
      gl.Enable(GL_BLEND);
      im.tx.BlendEquation(GL_FUNC_ADD);
      if (pass.kind == PassSpec::Light) {
        im.tx.BlendFunc(GL_DST_COLOR, GL_ZERO);
      } else {
        switch (st[std::size_t(pass.layer)].op) {
          case LayerOp::Blend:
            im.tx.BlendFunc(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA);
            break;
          case LayerOp::Add:
            im.tx.BlendFunc(GL_ONE, GL_ONE);
            break;
          case LayerOp::Subtract:
            im.tx.BlendEquation(GL_FUNC_REVERSE_SUBTRACT);
            im.tx.BlendFunc(GL_ONE, GL_ONE);
            break;
          case LayerOp::Multiply:
            im.tx.BlendFunc(GL_DST_COLOR, GL_ZERO);
            break;
        }
      }
    }
    const auto& base = options_.stack.base_color;
    gl.Uniform3f(p.u_base, base[0], base[1], base[2]);
    gl.Uniform3f(p.u_light, float(light.x), float(light.y), float(light.z));
    gl.Uniform1f(p.u_ambient, options_.ambient);
    for (std::size_t s = 0; s < p.sampled.size(); ++s)
      gl.Uniform1f(p.u_w[s], st[std::size_t(p.sampled[s].style)].weight);
    if (p.lens_unit >= 0) {
      im.tx.ActiveTexture(GL_TEXTURE0 + GLenum(p.lens_unit));
      im.tx.BindTexture(GL_TEXTURE_2D, im.lens_texture);
    }
    std::vector<GLuint> bound;
    for (std::size_t oi : order) {
      const LayeredItem& item = items[oi];
      auto mit = im.meshes.find(item.mesh.value);
      assert(mit != im.meshes.end() && "LayeredRenderer: unknown or removed MeshId");
      const GpuMesh& m = mit->second;
      const glm::mat4 mvp(pv * glm::translate(glm::dmat4(1.0), m.origin));
      gl.UniformMatrix4fv(p.u_mvp, 1, GL_FALSE, &mvp[0][0]);
      std::vector<GLuint> want;
      for (std::size_t s = 0; s < p.sampled.size(); ++s) {
        const SampledLayer& sl = p.sampled[s];
        const LayerBinding& b = item.layers[std::size_t(sl.style)];
        want.push_back(im.gl_texture(b.texture));
        if (sl.next_unit >= 0) want.push_back(im.gl_texture(b.next.value ? b.next : b.texture));
        // uv = ((x_rel + ox) / w, (oy - y_rel) / h), offsets formed in doubles.
        const GeoRect& g = b.georef;
        const bool valid = b.texture.value != 0 && g.width() > 0 && g.height() > 0;
        im.tx.Uniform4f(p.u_uv[s], valid ? float(m.origin.x - g.minx) : 0.0f,
                        valid ? float(g.maxy - m.origin.y) : 0.0f, valid ? float(1.0 / g.width()) : 0.0f,
                        valid ? float(1.0 / g.height()) : 0.0f);
        if (sl.next_unit >= 0) gl.Uniform1f(p.u_mix[s], b.next.value ? b.mix : 0.0f);
      }
      if (want != bound) {
        int unit = 0;
        for (std::size_t s = 0; s < p.sampled.size(); ++s) {
          const SampledLayer& sl = p.sampled[s];
          im.tx.ActiveTexture(GL_TEXTURE0 + GLenum(sl.unit));
          im.tx.BindTexture(GL_TEXTURE_2D, want[std::size_t(unit++)]);
          if (sl.next_unit >= 0) {
            im.tx.ActiveTexture(GL_TEXTURE0 + GLenum(sl.next_unit));
            im.tx.BindTexture(GL_TEXTURE_2D, want[std::size_t(unit++)]);
          }
        }
        bound = want;
        if (!p.sampled.empty()) ++stats.texture_binds;
      }
      if (p.lens_unit >= 0) {
        const GeoRect& g = lens.rect;
        im.tx.Uniform4f(p.u_lens_uv, float(m.origin.x - g.minx), float(g.maxy - m.origin.y),
                        float(1.0 / g.width()), float(1.0 / g.height()));
      }
      const std::size_t mesh_tris = m.indices / 3, first = std::min(item.first_triangle, mesh_tris);
      const std::size_t count = std::min(item.triangle_count, mesh_tris - first);
      if (count == 0) continue;
      gl.BindVertexArray(m.vao);
      gl.DrawElements(GL_TRIANGLES, GLsizei(3 * count), GL_UNSIGNED_INT,
                      reinterpret_cast<const void*>(3 * first * sizeof(std::uint32_t)));
      if (pi == 0) {
        ++stats.meshes;
        stats.triangles += count;
      }
    }
  }
  gl.BindVertexArray(0);
  gl.Disable(GL_BLEND);
  gl.DepthMask(GL_TRUE);
  im.tx.ActiveTexture(GL_TEXTURE0);
  detail::check_gl(gl, "layered renderer: drawing");
  if (options_.finish) gl.Finish();

  // Residency: evict texture_for() textures unused this frame, least recently used first.
  while (im.texture_bytes > options_.texture_budget_bytes) {
    auto victim = im.resident.end();
    for (auto it = im.resident.begin(); it != im.resident.end(); ++it)
      if (it->second.last_frame < im.frame &&
          (victim == im.resident.end() || it->second.last_frame < victim->second.last_frame))
        victim = it;
    if (victim == im.resident.end()) break;
    im.free_texture(victim->second.id.value);
  }
  stats.textures_uploaded = im.pending_uploads;
  stats.bytes_uploaded = im.pending_bytes;
  im.pending_uploads = im.pending_bytes = 0;
  stats.texture_bytes = texture_bytes();
  stats.draw_ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
  im.drawn = true;
  return stats;
}

FrameTarget LayeredRenderer::bind_frame() {
  assert(impl_->last_camera && "LayeredRenderer::bind_frame before the first draw()");
  ctx_.make_current();
  const detail::GlApi& gl = impl_->gl;
  const Camera& cam = *impl_->last_camera;
  gl.BindFramebuffer(GL_FRAMEBUFFER, impl_->target.fbo);
  gl.Viewport(0, 0, cam.width_px, cam.height_px);
  detail::check_gl(gl, "layered renderer: binding the frame");
  return {cam, false, projection_matrix(cam) * view_matrix(cam), options_.light_direction, options_.ambient};
}

Image LayeredRenderer::read_color() const {
  assert(impl_->drawn && "LayeredRenderer::read_color before the first draw()");
  ctx_.make_current();
  return impl_->target.read_rgb(impl_->gl, "layered renderer");
}

}  // namespace terralod::render
