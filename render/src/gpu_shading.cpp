// GPU generator of topographic (shading) textures: orthographic passes over texel space in an
// offscreen context, tiled beyond the framebuffer limits, read back as floats.
//
// Paper: Döllner, Baumann & Hinrichs, "Texturing techniques for terrain visualization"
// (generating topographic textures: orthographic projection into an offscreen buffer, tiling);
// formulas: topographic_texture.hpp (Horn 1981, Mark 1992 / GDAL multidirectional). The shader
// evaluates the CPU generator's expressions (shading_common.hpp) in the same order, in float.
// Memory: GPU 4 bytes per sample (R32F heights), 4 bytes per 16 x 16 cells (shadow index),
// + 8 per sample for RelativeHeight (RG32F
// row-wise min/max) + one R32F tile; CPU the output raster and one tile of floats.
#include "terralod/render/gpu_shading.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <limits>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>
#include <vector>

#include "gl_api.hpp"
#include "shading_common.hpp"

namespace terralod::render {
namespace {

constexpr int kMaxLights = 16;
constexpr float kHole = -1e30f;  // height of a hole in the texture (valid heights are >= 0)

const char* kVertex = R"(#version 330 core
layout(location = 0) in vec2 a_pos;   // texel-space corner of the tile
uniform mat4 u_proj;                  // orthographic projection of the tile
void main() { gl_Position = u_proj * vec4(a_pos, 0.0, 1.0); }
)";

// Shared declarations: heights relative to the lowest sample, holes at -1e30.
const char* kCommon = R"(#version 330 core
uniform sampler2D u_z;
uniform int u_w, u_h;
uniform vec2 u_tile;                  // texel index of the viewport's first fragment (integral)
bool valid(float z) { return z > -1e29; }
float zat(ivec2 p) { return texelFetch(u_z, p, 0).r; }
)";

// Pass 1 of relative-height shading: min/max of each sample's row window [c - R, c + R].
const char* kRowMinMax = R"(
uniform int u_radius;
out vec2 o_mm;
void main() {
  ivec2 p = ivec2(floor(gl_FragCoord.xy)) + ivec2(u_tile);
  float mn = 1e30, mx = -1e30;
  for (int k = max(0, p.x - u_radius); k <= min(u_w - 1, p.x + u_radius); ++k) {
    float z = zat(ivec2(k, p.y));
    if (valid(z)) { mn = min(mn, z); mx = max(mx, z); }
  }
  o_mm = vec2(mn, mx);
}
)";

const char* kShade = R"(
uniform sampler2D u_rowmm;            // pass 1 output (relative height, radius > 0)
uniform sampler2D u_bmax;             // shadow index: block maxima (relative heights)
uniform int u_block, u_bw, u_bh;      // cells per block edge, blocks across, blocks down
uniform int u_col0, u_row0, u_step;
uniform vec4 u_jt;                    // J^-T: gx = x*gc + y*gr, gy = z*gc + w*gr
uniform int u_method;                 // 0 Lambert, 1 Phong, 2 multidirectional, 3 relative
uniform int u_nl;
uniform vec3 u_l[16];                 // unit light vectors
uniform vec2 u_u[16];                 // grid direction per horizontal metre toward each light
uniform vec2 u_d[16];                 // horizontal unit directions (sin A, cos A)
uniform float u_tanh, u_bias, u_zmax, u_ambient;
uniform vec4 u_phong;                 // ka, kd, ks, shininess
uniform int u_shadows;
uniform int u_radius;
uniform vec2 u_grange;                // global min, max (relative height, radius 0)
out float o_v;

float zc(int c, int r, float e) {
  float z = zat(ivec2(clamp(c, 0, u_w - 1), clamp(r, 0, u_h - 1)));
  return valid(z) ? z : e;
}

bool line_height(int k, float s, bool along_col, out float h) {
  int s0 = int(floor(s));
  int s1 = min(s0 + 1, (along_col ? u_h : u_w) - 1);
  float fr = s - float(s0);
  float z0 = zat(along_col ? ivec2(k, s0) : ivec2(s0, k));
  float z1 = zat(along_col ? ivec2(k, s1) : ivec2(s1, k));
  h = 0.0;
  if (!valid(z0) || !valid(z1)) return false;
  h = z0 + (z1 - z0) * fr;
  return true;
}

// First index n >= n0 whose crossing n * dt is not below ts.
int first_not_below(int n0, float dt, float ts) {
  int n = max(n0, int(min(ts / dt, 1e9)));
  while (n > n0 && float(n - 1) * dt >= ts) --n;
  while (float(n) * dt < ts) ++n;
  return n;
}

// The CPU march (shading_common.hpp GridFrame::shadowed), block skipping included.
bool shadowed(int c0, int r0, float z0, vec2 u) {
  bool hc = u.x != 0.0, hr = u.y != 0.0;
  if (!hc && !hr) return false;
  int sc = u.x > 0.0 ? 1 : -1, sr = u.y > 0.0 ? 1 : -1;
  float dtc = hc ? 1.0 / abs(u.x) : 0.0, dtr = hr ? 1.0 / abs(u.y) : 0.0;
  int nc = 1, nr = 1;
  float t_prev = 0.0, t_block_end = -1.0;
  for (int it = 0; it < 4 * (u_w + u_h) + 8; ++it) {
    float tc = hc ? float(nc) * dtc : 3e38, tr = hr ? float(nr) * dtr : 3e38;
    float t = min(tc, tr);
    if (t_prev >= t_block_end) {
      float tm = 0.5 * (t_prev + t);
      int cell_c = clamp(int(floor(float(c0) + tm * u.x)), 0, max(0, u_w - 2));
      int cell_r = clamp(int(floor(float(r0) + tm * u.y)), 0, max(0, u_h - 2));
      int bx = min(cell_c / u_block, u_bw - 1), by = min(cell_r / u_block, u_bh - 1);
      float ec = hc ? (float(u.x > 0.0 ? (bx + 1) * u_block : bx * u_block) - float(c0)) / u.x : 3e38;
      float er = hr ? (float(u.y > 0.0 ? (by + 1) * u_block : by * u_block) - float(r0)) / u.y : 3e38;
      t_block_end = min(ec, er);
      if (z0 + t_prev * u_tanh > texelFetch(u_bmax, ivec2(bx, by), 0).r) {
        float ts = t_block_end * (1.0 - 1e-6);
        int nc2 = hc ? first_not_below(nc, dtc, ts) : nc;
        int nr2 = hr ? first_not_below(nr, dtr, ts) : nr;
        if (nc2 != nc || nr2 != nr) {
          t_prev = max(nc2 > nc ? float(nc2 - 1) * dtc : 0.0, nr2 > nr ? float(nr2 - 1) * dtr : 0.0);
          nc = nc2;
          nr = nr2;
          continue;
        }
      }
    }
    bool col_line = tc <= tr;
    float ray = z0 + t * u_tanh;
    if (ray > u_zmax) return false;
    float terrain;
    bool have;
    if (col_line) {
      int k = c0 + sc * nc;
      if (k < 0 || k >= u_w) return false;
      float rr = float(r0) + t * u.y;
      if (rr < 0.0 || rr > float(u_h - 1)) return false;
      have = line_height(k, rr, true, terrain);
      ++nc;
    } else {
      int k = r0 + sr * nr;
      if (k < 0 || k >= u_h) return false;
      float cc = float(c0) + t * u.x;
      if (cc < 0.0 || cc > float(u_w - 1)) return false;
      have = line_height(k, cc, false, terrain);
      ++nr;
    }
    t_prev = t;
    if (have && terrain - ray > u_bias) return true;
  }
  return false;
}

void main() {
  ivec2 texel = ivec2(floor(gl_FragCoord.xy)) + ivec2(u_tile);
  int col = u_col0 + texel.x * u_step, row = u_row0 + texel.y * u_step;
  float e = zat(ivec2(col, row));
  if (!valid(e)) { o_v = -1.0; return; }   // hole: NaN on the CPU side
  if (u_method == 3) {
    float mn = u_grange.x, mx = u_grange.y;
    if (u_radius > 0) {
      mn = 1e30; mx = -1e30;
      for (int r = max(0, row - u_radius); r <= min(u_h - 1, row + u_radius); ++r) {
        vec2 m = texelFetch(u_rowmm, ivec2(col, r), 0).rg;
        mn = min(mn, m.x); mx = max(mx, m.y);
      }
    }
    o_v = mx > mn ? (e - mn) / (mx - mn) : 0.5;
    return;
  }
  float a = zc(col - 1, row - 1, e), b = zc(col, row - 1, e), c = zc(col + 1, row - 1, e);
  float d = zc(col - 1, row, e), f = zc(col + 1, row, e);
  float g = zc(col - 1, row + 1, e), h = zc(col, row + 1, e), i = zc(col + 1, row + 1, e);
  float gc = ((c + 2.0 * f + i) - (a + 2.0 * d + g)) / 8.0;
  float gr = ((g + 2.0 * h + i) - (a + 2.0 * b + c)) / 8.0;
  float gx = u_jt.x * gc + u_jt.y * gr, gy = u_jt.z * gc + u_jt.w * gr;
  float len = sqrt(1.0 + gx * gx + gy * gy);
  vec3 n = vec3(-gx / len, -gy / len, 1.0 / len);
  if (u_method == 2) {
    float g2 = gx * gx + gy * gy, sw = 0.0, sd = 0.0;
    for (int k = 0; k < u_nl; ++k) {
      float gd = gx * u_d[k].x + gy * u_d[k].y;
      float w = g2 > 0.0 ? gd * gd / g2 : 1.0;
      float nl = dot(n, u_l[k]);
      bool lit = nl > 0.0 && (u_shadows == 0 || !shadowed(col, row, e, u_u[k]));
      sw += w;
      sd += w * (lit ? nl : 0.0);
    }
    o_v = u_ambient + (1.0 - u_ambient) * (sw > 0.0 ? sd / sw : 0.0);
    return;
  }
  float nl = dot(n, u_l[0]);
  bool on = nl > 0.0 && (u_shadows == 0 || !shadowed(col, row, e, u_u[0]));
  float dif = on ? nl : 0.0;
  if (u_method == 0) {
    o_v = u_ambient + (1.0 - u_ambient) * dif;
  } else {
    float rv = 2.0 * nl * n.z - u_l[0].z;
    float s = (on && rv > 0.0) ? pow(rv, u_phong.w) : 0.0;
    o_v = min(1.0, u_phong.x + u_phong.y * dif + u_phong.z * s);
  }
}
)";

// Every GL object of one call, deleted on every exit path.
struct Objects {
  const detail::GlApi& gl;
  GLuint shade = 0, rowmm = 0, vao = 0, vbo = 0, fbo = 0, rbo = 0, tex_z = 0, tex_mm = 0, tex_bmax = 0;
  explicit Objects(const detail::GlApi& g) : gl(g) {}
  ~Objects() {
    gl.BindFramebuffer(GL_FRAMEBUFFER, 0);
    gl.UseProgram(0);
    gl.BindVertexArray(0);
    if (shade) gl.DeleteProgram(shade);
    if (rowmm) gl.DeleteProgram(rowmm);
    if (vbo) gl.DeleteBuffers(1, &vbo);
    if (vao) gl.DeleteVertexArrays(1, &vao);
    if (fbo) gl.DeleteFramebuffers(1, &fbo);
    if (rbo) gl.DeleteRenderbuffers(1, &rbo);
    if (tex_z) gl.DeleteTextures(1, &tex_z);
    if (tex_mm) gl.DeleteTextures(1, &tex_mm);
    if (tex_bmax) gl.DeleteTextures(1, &tex_bmax);
  }
};

GLuint float_texture(const detail::GlApi& gl, GLint internal, GLenum format, int w, int h,
                     const float* data) {
  GLuint t = 0;
  gl.GenTextures(1, &t);
  gl.BindTexture(GL_TEXTURE_2D, t);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  gl.PixelStorei(GL_UNPACK_ALIGNMENT, 4);
  gl.TexImage2D(GL_TEXTURE_2D, 0, internal, w, h, 0, format, GL_FLOAT, data);
  return t;
}

/// Puts the quad of texels [x0, x0 + w] x [y0, y0 + h] into `vbo` and the orthographic
/// projection onto it into the uniform at `loc_proj` (the program in use).
void set_quad(const detail::GlApi& gl, GLuint vbo, GLint loc_proj, int x0, int y0, int w, int h) {
  const float fx0 = float(x0), fy0 = float(y0), fx1 = float(x0 + w), fy1 = float(y0 + h);
  const float quad[8] = {fx0, fy0, fx1, fy0, fx0, fy1, fx1, fy1};
  gl.BindBuffer(GL_ARRAY_BUFFER, vbo);
  gl.BufferSubData(GL_ARRAY_BUFFER, 0, sizeof quad, quad);
  const glm::mat4 proj = glm::ortho(fx0, fx1, fy0, fy1, -1.0f, 1.0f);
  gl.UniformMatrix4fv(loc_proj, 1, GL_FALSE, glm::value_ptr(proj));
}

}  // namespace

FloatRaster shade_terrain_gpu(const pm::Heightfield& hf, const ShadingOptions& o, const TexelRegion& region,
                              const GpuShadingOptions& gpu, GlContext* context, GpuShadingReport* report) {
  detail::validate_shading(hf, o, region, "shade_terrain_gpu");
  if (gpu.max_tile < 0) throw std::invalid_argument("shade_terrain_gpu: max_tile must be >= 0");
  const bool multi = o.method == ShadingMethod::Multidirectional;
  if (multi && o.multidirectional_azimuths.size() > std::size_t(kMaxLights))
    throw std::invalid_argument("shade_terrain_gpu: at most " + std::to_string(kMaxLights) +
                                " multidirectional azimuths");
  std::unique_ptr<GlContext> own;
  if (!context) {
    OffscreenOptions oo;
    oo.width = oo.height = 16;
    own = create_offscreen_context(oo);
    context = own.get();
  }
  context->make_current();
  const detail::GlApi& gl = context->api();
  const int W = hf.width(), H = hf.height();
  const int ow = region.out_width(W), oh = region.out_height(H);

  GLint max_tex = 0, max_rb = 0, vp[2] = {0, 0};
  gl.GetIntegerv(GL_MAX_TEXTURE_SIZE, &max_tex);
  gl.GetIntegerv(GL_MAX_RENDERBUFFER_SIZE, &max_rb);
  gl.GetIntegerv(GL_MAX_VIEWPORT_DIMS, vp);
  if (W > max_tex || H > max_tex)
    throw RenderError("gpu shading: the " + std::to_string(W) + " x " + std::to_string(H) +
                      " heightfield exceeds GL_MAX_TEXTURE_SIZE " + std::to_string(max_tex));
  int tile = std::min({int(max_rb), int(vp[0]), int(vp[1])});
  if (gpu.max_tile > 0) tile = std::min(tile, gpu.max_tile);
  const int tw = std::min(tile, ow), th = std::min(tile, oh);

  // Heights relative to the lowest valid sample (float keeps ~1e-4 m on a 2 km relief).
  detail::GridFrame f(hf, o.vertical_exaggeration);
  f.build_shadow_index();
  double base = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < hf.size(); ++i)
    if (hf.valid(i)) base = std::min(base, hf[i] * f.ez);
  std::vector<float> z(hf.size(), kHole);
  double gmin = std::numeric_limits<double>::infinity(), gmax = -gmin;
  for (std::size_t i = 0; i < hf.size(); ++i)
    if (hf.valid(i)) {
      z[i] = static_cast<float>(hf[i] * f.ez - base);
      gmin = std::min<double>(gmin, z[i]), gmax = std::max<double>(gmax, z[i]);
    }

  Objects obj(gl);
  obj.shade = detail::build_program(gl, kVertex, std::string(kCommon) + kShade, "gpu shading (shading)");
  gl.GenVertexArrays(1, &obj.vao);
  gl.BindVertexArray(obj.vao);
  gl.GenBuffers(1, &obj.vbo);
  gl.BindBuffer(GL_ARRAY_BUFFER, obj.vbo);
  gl.BufferData(GL_ARRAY_BUFFER, 8 * sizeof(float), nullptr, GL_DYNAMIC_DRAW);
  gl.EnableVertexAttribArray(0);
  gl.VertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, 0, nullptr);
  gl.Disable(GL_DEPTH_TEST);
  gl.Disable(GL_BLEND);
  gl.ActiveTexture(GL_TEXTURE0);
  obj.tex_z = float_texture(gl, GL_R32F, GL_RED, W, H, z.data());
  std::vector<float> bmax(f.block_max().size());
  for (std::size_t i = 0; i < bmax.size(); ++i)
    bmax[i] = std::isfinite(f.block_max()[i]) ? static_cast<float>(f.block_max()[i] - base) : kHole;
  gl.ActiveTexture(GL_TEXTURE2);
  obj.tex_bmax = float_texture(gl, GL_R32F, GL_RED, f.blocks_x(), f.blocks_y(), bmax.data());
  gl.ActiveTexture(GL_TEXTURE0);
  gl.GenFramebuffers(1, &obj.fbo);
  gl.BindFramebuffer(GL_FRAMEBUFFER, obj.fbo);
  detail::check_gl(gl, "gpu shading: uploading the heights");

  const bool relative = o.method == ShadingMethod::RelativeHeight;
  if (relative && o.relative_radius > 0) {
    // Pass 1: row-wise min/max over the whole grid into an RG32F texture, tile by tile.
    obj.rowmm =
        detail::build_program(gl, kVertex, std::string(kCommon) + kRowMinMax, "gpu shading (row min/max)");
    gl.ActiveTexture(GL_TEXTURE1);
    obj.tex_mm = float_texture(gl, GL_RG32F, GL_RG, W, H, nullptr);
    gl.ActiveTexture(GL_TEXTURE0);
    gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, obj.tex_mm, 0);
    if (gl.CheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
      throw RenderError("gpu shading: the RG32F min/max framebuffer is incomplete");
    gl.UseProgram(obj.rowmm);
    gl.Uniform1i(gl.GetUniformLocation(obj.rowmm, "u_z"), 0);
    gl.Uniform1i(gl.GetUniformLocation(obj.rowmm, "u_w"), W);
    gl.Uniform1i(gl.GetUniformLocation(obj.rowmm, "u_h"), H);
    gl.Uniform1i(gl.GetUniformLocation(obj.rowmm, "u_radius"), o.relative_radius);
    const GLint loc_tile = gl.GetUniformLocation(obj.rowmm, "u_tile");
    for (int y0 = 0; y0 < H; y0 += tile)
      for (int x0 = 0; x0 < W; x0 += tile) {
        const int w = std::min(tile, W - x0), h = std::min(tile, H - y0);
        // Render into the texture's sub-rectangle: the viewport is offset, fragments know it.
        set_quad(gl, obj.vbo, gl.GetUniformLocation(obj.rowmm, "u_proj"), x0, y0, w, h);
        gl.Uniform2f(loc_tile, 0.0f, 0.0f);  // the viewport is offset: gl_FragCoord is absolute
        gl.Viewport(x0, y0, w, h);
        gl.DrawArrays(GL_TRIANGLE_STRIP, 0, 4);
      }
    gl.Finish();
    detail::check_gl(gl, "gpu shading: row min/max pass");
  }

  // Output tiles: an R32F renderbuffer of tw x th.
  gl.GenRenderbuffers(1, &obj.rbo);
  gl.BindRenderbuffer(GL_RENDERBUFFER, obj.rbo);
  gl.RenderbufferStorage(GL_RENDERBUFFER, GL_R32F, tw, th);
  gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, 0, 0);
  gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, obj.rbo);
  if (gl.CheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    throw RenderError("gpu shading: the R32F tile framebuffer is incomplete");
  gl.ReadBuffer(GL_COLOR_ATTACHMENT0);

  const GLuint p = obj.shade;
  gl.UseProgram(p);
  auto loc = [&](const char* n) { return gl.GetUniformLocation(p, n); };
  gl.Uniform1i(loc("u_z"), 0);
  gl.Uniform1i(loc("u_rowmm"), 1);
  gl.Uniform1i(loc("u_bmax"), 2);
  gl.Uniform1i(loc("u_block"), detail::GridFrame::kBlock);
  gl.Uniform1i(loc("u_bw"), f.blocks_x());
  gl.Uniform1i(loc("u_bh"), f.blocks_y());
  gl.Uniform1i(loc("u_w"), W);
  gl.Uniform1i(loc("u_h"), H);
  gl.Uniform1i(loc("u_col0"), region.col0);
  gl.Uniform1i(loc("u_row0"), region.row0);
  gl.Uniform1i(loc("u_step"), region.step);
  {
    // J^-T from the frame: gradient of a unit column step and a unit row step.
    const auto& t = hf.transform;
    const double det = t.determinant();
    gl.Uniform4f(loc("u_jt"), float(t.yr / det), float(-t.yc / det), float(-t.xr / det), float(t.xc / det));
  }
  gl.Uniform1i(loc("u_method"), int(o.method));
  const std::vector<double> az = multi ? o.multidirectional_azimuths : std::vector<double>{o.azimuth_deg};
  gl.Uniform1i(loc("u_nl"), int(az.size()));
  for (std::size_t k = 0; k < az.size(); ++k) {
    const Vec3d l = light_direction(az[k], o.altitude_deg);
    const double ar = az[k] * std::numbers::pi / 180.0;
    double uc, ur;
    f.grid_direction(std::sin(ar), std::cos(ar), uc, ur);
    char name[3][32];
    for (int v = 0; v < 3; ++v) std::snprintf(name[v], sizeof name[v], "u_%c[%zu]", "lud"[v], k);
    gl.Uniform3f(loc(name[0]), float(l.x), float(l.y), float(l.z));
    gl.Uniform2f(loc(name[1]), float(uc), float(ur));
    gl.Uniform2f(loc(name[2]), float(std::sin(ar)), float(std::cos(ar)));
  }
  gl.Uniform1f(loc("u_tanh"), float(std::tan(o.altitude_deg * std::numbers::pi / 180.0)));
  gl.Uniform1f(loc("u_bias"), float(o.shadow_bias));
  gl.Uniform1f(loc("u_zmax"), float(f.zmax - base));
  gl.Uniform1f(loc("u_ambient"), float(o.ambient));
  gl.Uniform4f(loc("u_phong"), float(o.phong_ka), float(o.phong_kd), float(o.phong_ks),
               float(o.phong_shininess));
  gl.Uniform1i(loc("u_shadows"), o.shadows ? 1 : 0);
  gl.Uniform1i(loc("u_radius"), relative ? o.relative_radius : 0);
  gl.Uniform2f(loc("u_grange"), float(gmin), float(gmax));
  const GLint loc_tile = loc("u_tile");
  const GLint loc_proj = loc("u_proj");

  FloatRaster out(ow, oh);
  std::vector<float> buf(std::size_t(tw) * th);
  int tiles = 0;
  gl.PixelStorei(GL_PACK_ALIGNMENT, 4);
  for (int j0 = 0; j0 < oh; j0 += th)
    for (int i0 = 0; i0 < ow; i0 += tw) {
      const int w = std::min(tw, ow - i0), h = std::min(th, oh - j0);
      set_quad(gl, obj.vbo, loc_proj, i0, j0, w, h);
      gl.Uniform2f(loc_tile, float(i0), float(j0));
      gl.Viewport(0, 0, w, h);
      gl.DrawArrays(GL_TRIANGLE_STRIP, 0, 4);
      gl.ReadPixels(0, 0, w, h, GL_RED, GL_FLOAT, buf.data());
      detail::check_gl(gl, "gpu shading: drawing a tile");
      for (int y = 0; y < h; ++y)  // framebuffer row y = texel row j0 + y (top row first)
        for (int x = 0; x < w; ++x) {
          const float v = buf[std::size_t(y) * w + x];
          out.at(i0 + x, j0 + y) = v < 0.0f ? std::numeric_limits<float>::quiet_NaN() : v;
        }
      ++tiles;
    }
  if (report) {
    report->tiles = tiles;
    report->tile_width = tw;
    report->tile_height = th;
    report->renderer = context->info().renderer;
  }
  return out;
}

}  // namespace terralod::render
