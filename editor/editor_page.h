// One page of the browser editor, without sockets: the JSON requests of docs/editor.md
// turned into EditorSession calls (apps/editor_session.h), the 60 Hz update frames,
// uploads and saves, with every reply handed to a PageSink. meshpde serve
// (serve.cpp) gives each page a worker thread and a sink that queues frames for the
// I/O thread; the fuzz targets editor_message and editor_upload call it in process.
// Not thread-safe: one thread at a time (the page's worker).
//
// Wire format (little-endian): every binary frame starts with a four-byte tag.
//   "MESH" u32 nv, u32 nf, f32 positions[3 nv], u32 triangles[3 nf]
//   "POS " u32 n, u32 ids[n], f32 positions[3 n]
//   "FLD " u32 nv, f32 values[nv]
//   "VEC " u32 n, u32 ids[n], f32 vectors[3 n]   (arrows; n = 0 clears them)
//   "SLC " u32 axis (0 axial, 1 coronal, 2 sagittal), u32 width, u32 height, u32 seq,
//          f32 position, f32 origin[3], f32 u[3], f32 v[3], u8 pixels[width * height]
//          (a slice of the image: pixel (a, b) at origin + a u + b v, row b at b * width)
//   "RIM " u32 seq, u32 region vertices, f32 radius, f32 handle radius, u32 n, u32 m,
//          f32 segments[6 (n + m)]   (what a drag at the hovered point would touch: n
//          segments of the region's rim, then m of the handle's, each two points)
//   "REG " u32 n, u32 ids[n]   (the vertices a drag can move; sent before drag_begin's reply)
// Text frames are JSON objects with a "type" (see docs/editor.md).
#pragma once

#include <Eigen/Core>
#include <chrono>
#include <functional>
#include <memory>
#include <nlohmann/json_fwd.hpp>
#include <string>

#include "meshpde/editor/editor_session.h"
#include "meshpde/image/volume.h"
#include "meshpde/io/mesh_io.h"
#include "meshpde/mesh/units.h"

namespace meshpde::editor {

/// A mesh with the name and format it came in, so saving writes the same format.
struct Loaded {
  MeshData data;
  std::string name = "mesh.ply";
  bool from_segmentation = false;  ///< the surface of the server's segment (saving writes it back)
  /// Unit of `data`'s coordinates (meshpde serve --units). A page works in millimetres,
  /// as the image and every length typed are, and saves in this unit.
  LengthUnit units = LengthUnit::Millimetre;
};

/// The segmentation a server opened (meshpde serve --segmentation): its segment's
/// surface is what pages edit, and a page's save_segmentation puts the edited surface
/// back into a copy written to `output` (beside the input unless --overwrite).
struct EditorSegmentation;
/// Reads `path`, picks `segment` (name, ID or label value; empty: the only one) and
/// decides where saving writes. \throw InputError naming the file.
std::shared_ptr<const EditorSegmentation> load_editor_segmentation(const std::string& path, const std::string& segment,
                                                                   bool overwrite);
/// The segment's surface (apps/segment_surface.h, LPS mm) as the mesh pages open.
Loaded segmentation_surface(const EditorSegmentation& s);

/// A mesh file's bytes, read by the format its name's extension says (.vtp/.vtk need
/// meshpde::medical). \throw InputError naming the file.
Loaded parse_mesh_bytes(const std::string& bytes, const std::string& name);
/// A mesh written in the format of `name`'s extension.
std::string mesh_bytes(const MeshData& d, const std::string& name);
/// The editor's "open" menu: the library's generator table (mesh/generators.h) with
/// presets sized for a vessel-scale view, plus "dented" (the bifurcation with its dent).
/// \throw InputError for an unknown kind.
Loaded generated(const std::string& requested);

/// The volume beside the meshes (meshpde serve --image), shared read-only by every
/// page: shown as slices, and its edge map guides corrections.
struct EditorImage {
  std::shared_ptr<const Volume> volume;  ///< as read: the slices
  std::shared_ptr<const Volume> edges;   ///< |grad| of the smoothed volume: guides corrections
  double low = 0, high = 1;              ///< 1st and 99th percentiles of the values: the default window
  double min = 0, max = 1;               ///< the values' range (the window sliders' limits)
  std::string name;                      ///< file name, for the page
};

/// Reads `path` and prepares it for pages (edge map, default window).
/// \throw InputError naming the file.
std::shared_ptr<const EditorImage> load_editor_image(const std::string& path, const std::string& series = "");
/// The same for a volume read already; `name` is shown on the page.
std::shared_ptr<const EditorImage> prepare_editor_image(Volume volume, const std::string& name);
/// Whether an upload named `name` is a saved editor session (*.meshpde: EditorPage::save_session).
bool is_session_file(const std::string& name);
/// Whether an upload named `name` is a volume (by its extension; a .zip holds a DICOM
/// series) rather than a mesh.
bool is_volume_upload(const std::string& name);

/// Where a page's frames go: JSON text and binary.
struct PageSink {
  std::function<void(std::string)> text;
  std::function<void(std::string)> binary;
};

/// What an editor save writes besides the mesh (EditorPage::save).
struct SaveOptions {
  std::string format{};       ///< vtp, vtk, stl, ply, obj or off; empty: the format it came in
  bool displacement = false;  ///< add the point field "displacement" (3 components, the mesh's unit)
};

class EditorPage {
 public:
  /// A page with no mesh yet; `image` (may be null) is shown and guides corrections,
  /// `space` is the frame of the meshes' coordinates, `upload_units` the unit of the
  /// meshes uploaded to it.
  EditorPage(PageSink sink, std::shared_ptr<const EditorImage> image, Space space,
             LaplacianKind laplacian = LaplacianKind::Auto,
             std::shared_ptr<const EditorSegmentation> segmentation = nullptr,
             LengthUnit upload_units = LengthUnit::Millimetre);

  /// Opens `l` (a new session) and sends it: a "mesh" message and a MESH frame.
  /// \throw InputError (the page keeps its mesh).
  void load(Loaded l);
  /// One request (a WebSocket message); every error goes back to the page as an
  /// {"type": "error"} message and changes nothing.
  void handle(const std::string& payload, bool binary);
  /// One update: advances a playing simulation and sends what changed.
  void frame();
  /// Parses, checks and opens an uploaded file; returns its vertex count.
  /// \throw InputError naming the file (the page keeps its mesh).
  int upload(const std::string& bytes, const std::string& name);
  /// An uploaded volume (.mha, .nii, .nii.gz, .nrrd: one file; .zip: a DICOM series) beside the page's mesh:
  /// shown as slices and guiding corrections from now on, in the page's frame; the
  /// page gets an {"type": "image"} message. Edits so far are kept. A header that
  /// declares more than kMaxUploadedVoxels is refused before any voxel is read.
  /// \throw InputError naming the file (the page keeps its image, if any).
  void upload_image(const std::string& bytes, const std::string& name);
  /// 512 x 512 x 1,024: the page keeps the volume and its edge image (8 bytes a voxel,
  /// 2 GB at this size), and a compressed upload of --max-upload-mb can declare 1,032
  /// times its bytes.
  static constexpr std::size_t kMaxUploadedVoxels = std::size_t{512} * 512 * 1024;
  /// The current mesh and the name to download it as (NAME-edited.EXT), in the unit it
  /// came in, with its arrays and their types (Float32 points stay Float32), normal
  /// arrays recomputed when vertices moved (they would be stale), and the page's frame
  /// as the SPACE tag (.vtp field data, .vtk title).
  /// \throw InputError with no mesh loaded or an unknown format.
  std::pair<std::string, std::string> save(const SaveOptions& options = {}) const;
  /// The page's session as one file and the name to download it as (NAME-session.meshpde):
  /// the mesh as it was opened (every array kept), every correction with the undo and
  /// redo history and the step shown, the tissue brushes, the image (as read) and the
  /// frame, and `page` (a JSON object: the page's own settings, given back on reopening).
  /// Paint, heat and wave are not kept. \throw InputError with no mesh loaded or `page`
  /// not a JSON object.
  std::pair<std::string, std::string> save_session(const std::string& page) const;
  /// Reopens a saved session (an upload named *.meshpde): its mesh, history at its step,
  /// tissue, image (else the page keeps its own) and frame; the "mesh" message carries
  /// its page settings. Returns the vertex count. \throw InputError naming the file and
  /// what is wrong (the page keeps what it had).
  int open_session(const std::string& bytes, const std::string& name);

 private:
  // Makes `session` (built for `l`) the page's and sends it: a "mesh" message (with a
  // reopened session's page settings, `page`) and a MESH frame.
  void open(Loaded l, std::unique_ptr<EditorSession> session, const nlohmann::json& page);
  void send_json(const nlohmann::json& j);
  void send_binary(std::string bytes);
  void send_stats(bool now);
  void send_slice(const nlohmann::json& request);
  void send_rim(const nlohmann::json& request);
  nlohmann::json image_json() const;
  nlohmann::json save_segmentation();

  PageSink sink_;
  std::shared_ptr<const EditorImage> image_;
  Space space_;
  LaplacianKind laplacian_;
  std::shared_ptr<const EditorSegmentation> segmentation_;
  LengthUnit upload_units_;
  Loaded source_;
  std::unique_ptr<EditorSession> session_;
  Positions sent_;                 // positions as the page has them
  Eigen::VectorXd sent_field_;     // field as the page has it
  Eigen::MatrixX3d sent_vectors_;  // vector field as the page has it
  std::string sent_field_name_;
  CorrectionParams tissue_;  // the page's brushes: stiffness and tissue fields (empty: uniform)
  int intersections_ = 0;
  double frame_ms_ = 0;  // time to build the last frame
  std::chrono::steady_clock::time_point last_stats_{};
};

}  // namespace meshpde::editor
