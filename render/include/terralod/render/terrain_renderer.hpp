// TerrainRenderer: uploads DrawMeshes to the GPU and draws them lit, with geomorphs and an
// optional wireframe, into an offscreen framebuffer that can be read back or shown in a window.
//
// Usage:
//   auto ctx = terralod::render::create_offscreen_context();
//   terralod::render::TerrainRenderer r(*ctx);
//   terralod::render::MeshId id = r.upload(draw_mesh);           // static vertices + index list
//   r.update_indices(id, new_indices);                           // per frame, cheap
//   terralod::render::FrameStats s = r.draw(camera, {{id, /*alpha=*/0.25f}});
//   terralod::render::write_png(r.read_color(), "frame.png");
//   std::vector<terralod::render::DepthSample> d = r.read_depth({{640, 360}});
//   // d[0].distance: metres from the camera to the terrain through that pixel's centre
//   r.present();                                                  // window contexts: show it
//
// Model and choices:
//   - Vertex data lives on the GPU relative to each mesh's origin (floats); the model-view-
//     projection matrix P * V * T(origin) is formed in doubles and only then rounded to float,
//     so UTM-sized coordinates never meet float arithmetic.
//   - Geomorphs: every vertex carries two heights z0 (xyz.z) and z1 (z_target); a draw at
//     alpha shows z = (1-alpha) z0 + alpha z1 (exactly z0 at 0 and z1 at 1).
//     GeomorphPath::Gpu (the default) blends in the vertex shader: a frame uploads nothing.
//     GeomorphPath::Cpu blends on the CPU in float with the same formula (no FMA contraction)
//     and uploads one float per vertex when alpha changes. Both give the same picture (the
//     tests find them byte-identical; they require 1 LSB).
//     Measured (Timing test, llvmpipe on 2 shared cores, 513 x 513 terrain reduced to 200,875
//     triangles / 101,025 vertices, alpha changing every frame): CPU path 0.08-0.14 ms of
//     blend + upload (404 kB) per frame, GPU path 0; draw time equal within noise for both
//     (about 52 ms at 1024 x 768, 31 ms at 256 x 192: the two extra multiply-adds per vertex
//     do not show). GPU is the default: it costs no CPU time or bus bandwidth per frame, keeps
//     every vertex buffer immutable (no orphaning, no CPU/GPU synchronisation), and its cost
//     does not grow with the number of morphing vertices (the CPU path's grows ~1 ns each).
//     The CPU path stays as the reference the GPU path is tested against.
//   - Lighting: one directional light (Lambert plus ambient) over a height colour ramp.
//     Normals are per vertex: DrawMesh::normals when given (make_draw_mesh takes them from the
//     full-resolution samples, so shading does not pop as the mesh coarsens or morphs),
//     otherwise area-weighted triangle normals computed once at upload.
//   - Depth: a 32-bit float depth buffer; with glClipControl (GL 4.5, llvmpipe has it) and
//     RendererOptions::reverse_z, reverse-Z (near -> 1, far -> 0) keeps about 24 bits of
//     relative precision at every distance. read_depth() unprojects in doubles; against a
//     ray-cast plane 0.5 km away the distance is within 4.4e-7 relative with reverse-Z and
//     5.6e-5 with the standard mapping (near 1 m, far 5 km).
//   - No back-face culling (a camera under a cliff still sees it), no multisampling (frames
//     are deterministic: the same inputs give byte-identical pixels on one driver).
//
// Contract:
//   - The renderer uses its context (made current in every call) and must be destroyed
//     before it. Not thread-safe; one renderer per context at a time is the intended use.
//   - upload/replace/update_* validate their input and throw std::invalid_argument naming
//     the problem (sizes, an index beyond the vertex count); a MeshId that was never returned
//     or was removed is a programming error (assert), as is read_* before the first draw().
//   - GL failures (framebuffer incomplete, shader errors) throw RenderError.
//   - Memory on the GPU per mesh: 28 bytes per vertex (x, y, normal; z0, z1) + 4 bytes per
//     index (capacity grows by 1.5x) + 4 bytes per vertex once the CPU path has blended it.
//     On the CPU: 8 bytes per vertex (z0, z1, kept for the CPU path and for new targets) + 4
//     more once the CPU path has blended. The frame: 8 bytes per pixel (RGBA8 + 32-bit depth).
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/glm.hpp>
#include <initializer_list>
#include <memory>
#include <span>
#include <vector>

#include "terralod/render/camera.hpp"
#include "terralod/render/draw_mesh.hpp"
#include "terralod/render/gl_context.hpp"
#include "terralod/render/image.hpp"

namespace terralod::render {

/// Where geomorph heights are blended.
enum class GeomorphPath : std::uint8_t {
  Gpu,  ///< in the vertex shader from z0, z1 and a uniform alpha (default)
  Cpu,  ///< on the CPU, uploaded as one float per vertex when alpha changes
};

struct RendererOptions {
  GeomorphPath geomorph = GeomorphPath::Gpu;
  bool wireframe = false;                        ///< draw triangle edges over the shaded surface
  glm::vec3 sky_color{0.62f, 0.75f, 0.88f};      ///< background, linear RGB in [0,1]
  glm::vec3 wire_color{0.10f, 0.10f, 0.12f};     ///< wireframe lines
  glm::dvec3 light_direction{-0.5, 0.5, 0.707};  ///< towards the light, world frame (normalised)
  float ambient = 0.35f;                         ///< share of light that ignores the normal, [0,1]
  /// World heights (metres) at the two ends of the colour ramp (green, brown, grey, white);
  /// ramp_low >= ramp_high means "the height range of the meshes currently uploaded".
  double ramp_low = 0.0, ramp_high = 0.0;
  bool reverse_z = true;  ///< use reverse-Z when the context has glClipControl
  /// glFinish at the end of draw(), so FrameStats::draw_ms is what the frame cost. Off lets
  /// the driver overlap frames with the CPU's work (a window's swap synchronises anyway).
  bool finish = true;
};

/// Handle of an uploaded mesh. Value 0 is never a valid mesh.
struct MeshId {
  std::uint32_t value = 0;
  bool operator==(const MeshId&) const = default;
};

/// One mesh to draw in a frame, at a geomorph blend alpha in [0, 1].
struct DrawItem {
  MeshId mesh;
  float alpha = 0.0f;
};

/// What a frame cost and contained.
struct FrameStats {
  std::size_t meshes = 0;
  std::size_t triangles = 0;
  std::size_t bytes_uploaded = 0;  ///< CPU geomorph heights uploaded this frame
  double upload_ms = 0.0;          ///< CPU blend + upload of geomorph heights
  double draw_ms = 0.0;            ///< clear + draw calls (+ glFinish when options.finish)
};

/// The last frame as a target to draw more into (object_renderer.hpp): its camera, depth
/// convention and world -> clip matrix (doubles; translate to a nearby origin before floats).
struct FrameTarget {
  Camera camera;
  bool reverse_z = false;           ///< true: near -> depth 1, far -> 0 (GL_GREATER passes nearer)
  glm::dmat4 view_projection{1.0};  ///< clip from world, the projection the terrain was drawn with
  glm::dvec3 light_direction{-0.5, 0.5, 0.707};  ///< the terrain's light (towards it, world frame)
  float ambient = 0.35f;                         ///< the terrain's ambient share
};

/// A renderer whose last frame objects can be drawn into (TerrainRenderer, LayeredRenderer).
class FrameSource {
 public:
  /// Binds the last frame's framebuffer (its colour and depth, as draw() left them), viewport
  /// and depth convention, so that what is drawn next is depth-tested against the terrain and
  /// the renderer's read_color() shows it. Asserts after the first draw(); the next draw()
  /// clears it.
  virtual FrameTarget bind_frame() = 0;

 protected:
  ~FrameSource() = default;
};

/// Depth read back at one pixel of the last frame.
struct DepthSample {
  glm::ivec2 pixel{0, 0};     ///< image coordinates, (0,0) = top-left pixel
  bool hit = false;           ///< false: the ray through the pixel centre met no terrain
  double window_depth = 0.0;  ///< the depth buffer's value, [0,1] (reverse-Z: 1 = near)
  double eye_depth = 0.0;     ///< metres along the view axis (-z in eye space); +inf if !hit
  double distance = 0.0;      ///< metres from the camera to the surface point; +inf if !hit
  glm::dvec3 world{0.0};      ///< that surface point, world frame
};

class TerrainRenderer : public FrameSource {
 public:
  /// Compiles the shaders; throws RenderError on failure. Keeps a reference to `context`.
  explicit TerrainRenderer(GlContext& context, const RendererOptions& options = {});
  ~TerrainRenderer();
  TerrainRenderer(const TerrainRenderer&) = delete;
  TerrainRenderer& operator=(const TerrainRenderer&) = delete;

  /// Options apply from the next draw(); they may be changed between frames.
  RendererOptions& options() { return options_; }
  const RendererOptions& options() const { return options_; }
  const GlContext& context() const { return ctx_; }

  /// Copies the mesh to GPU buffers (see DrawMesh's contract); returns its handle.
  MeshId upload(const DrawMesh& mesh);
  /// Replaces a mesh's data, reusing its buffers where they are large enough.
  void replace(MeshId id, const DrawMesh& mesh);
  /// Replaces the triangle list only (3 indices per triangle, each < the vertex count).
  /// O(indices): one buffer write, no reallocation unless the list outgrows the capacity.
  void update_indices(MeshId id, std::span<const std::uint32_t> indices);
  /// Replaces the heights at alpha = 1 (one float per vertex, relative to origin.z).
  void update_target_heights(MeshId id, std::span<const float> z_target);
  /// Frees a mesh's GPU buffers; its handle becomes invalid.
  void remove(MeshId id);
  std::size_t vertex_count(MeshId id) const;
  std::size_t triangle_count(MeshId id) const;
  /// GPU memory held by the meshes' buffers, bytes.
  std::size_t gpu_bytes() const;

  /// Draws a frame of camera.width x camera.height pixels into the offscreen framebuffer
  /// (reallocated when the size changes). Items with alpha outside [0,1] are a programming
  /// error (assert).
  FrameStats draw(const Camera& camera, std::span<const DrawItem> items);
  FrameStats draw(const Camera& camera, std::initializer_list<DrawItem> items) {
    return draw(camera, std::span<const DrawItem>(items.begin(), items.size()));
  }

  /// The last frame's colour, top row first.
  Image read_color() const;
  /// The last frame as it lands in the context's default framebuffer (blitted there first):
  /// for a window, what present() would show. Same size as the context's framebuffer. With
  /// blit = false the default framebuffer is read as it is (after present(false) and an
  /// overlay: the picture with its heads-up display).
  Image read_window_color(bool blit = true);
  /// Depth at the given pixels of the last frame (image coordinates, inside the frame),
  /// unprojected with the last frame's camera. Reads the pixels' bounding rectangle once.
  std::vector<DepthSample> read_depth(std::span<const glm::ivec2> pixels) const;
  std::vector<DepthSample> read_depth(std::initializer_list<glm::ivec2> pixels) const {
    return read_depth(std::span<const glm::ivec2>(pixels.begin(), pixels.size()));
  }
  FrameTarget bind_frame() override;  ///< see FrameSource
  /// Copies the last frame to the default framebuffer (scaled to its size) and swaps; with
  /// swap = false it only copies, so that an overlay (hud.hpp) can be drawn before the swap.
  void present(bool swap = true);

 private:
  struct Impl;
  GlContext& ctx_;
  RendererOptions options_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace terralod::render
