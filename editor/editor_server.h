// The browser editor's server: one HTTP and WebSocket port serving the built page
// (web/dist), uploads and downloads, and per page an EditorPage (editor_page.h) whose
// EditorSession (meshpde/editor/editor_session.h) does the numerics. `meshpde serve`
// parses these options and calls serve(); docs/editor.md describes the editor.
#pragma once

#include <string>

namespace meshpde::editor {

struct EditorServerOptions {
  /// A mesh to open, or a session saved by the page (.meshpde); empty: a generated
  /// dented bifurcation.
  std::string mesh;
  std::string host = "127.0.0.1";  ///< address to bind (loopback by default)
  int port = 8080;                 ///< TCP port; 0: any free port
  std::string image;               ///< volume (or DICOM series) shown beside the mesh and guiding corrections
  std::string series;              ///< DICOM folder of several series: the one to show
  std::string segmentation;        ///< open this segmentation's segment surface instead of a mesh
  std::string segment;             ///< the segment (name, ID or label value) among several
  bool overwrite = false;          ///< saving writes the corrected segmentation over the input
  std::string space;               ///< "lps" | "ras" | empty: the mesh file's tag, else LPS
  std::string units = "mm";        ///< the mesh's unit: mm | cm | m
  std::string laplacian = "auto";  ///< auto | cotan | intrinsic
  std::string web_root;            ///< folder of the built page (default_web_root())
  double max_upload_mb = 64;       ///< largest accepted upload
};

/// The built page: installed beside the tool (found from the executable's own path),
/// else the source tree's web/dist this binary was built from.
std::string default_web_root();

/// Serves until SIGINT or SIGTERM. \throw InputError for options or inputs that cannot
/// be used (named), std::runtime_error when the port cannot be bound.
void serve(const EditorServerOptions& options);

}  // namespace meshpde::editor
