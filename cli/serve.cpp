// meshpde serve: parses the editor's options and starts its server (editor/, the
// meshpde::editor component: editor_server.h).
#include <fmt/format.h>

#include <memory>

#include "commands.h"
#include "editor_server.h"
#include "meshpde/core/errors.h"

namespace meshpde::cli {

void add_serve_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("serve", "Interactive browser editor: poke, correct, paint, heat and wave, live");
  auto a = std::make_shared<editor::EditorServerOptions>();
  a->web_root = editor::default_web_root();
  cmd->add_option("MESH", a->mesh,
                  "Mesh to open, or a session saved by the page (.meshpde) (default: a generated dented bifurcation)");
  cmd->add_option("--port", a->port, "TCP port (0: any free port)")->capture_default_str();
  cmd->add_option("--host", a->host, "Address to bind (default loopback only; 0.0.0.0 exposes the editor)")
      ->capture_default_str();
  cmd->add_option("--image", a->image,
                  "Volume for image-guided correction (.mha .mhd .nii .nii.gz .nrrd .nhdr, or a DICOM series: a folder "
                  "or one file of it)");
  cmd->add_option("--series", a->series, "DICOM folder of several series: the one to show (UID or series number)");
  cmd->add_option("--segmentation", a->segmentation,
                  "Open a segmentation (3D Slicer .seg.nrrd, or a label map .nii .nii.gz .nrrd .mha): pages edit its "
                  "segment's surface, and saving writes the corrected segmentation beside it as NAME-corrected");
  cmd->add_option("--segment", a->segment, "The segment to edit: name, ID or label value (needed among several)");
  cmd->add_flag("--overwrite", a->overwrite, "Saving writes the corrected segmentation over the input itself");
  cmd->add_option("--space", a->space, "Frame of the mesh coordinates: lps | ras");
  cmd->add_option(
         "--units", a->units,
         "Unit of the mesh coordinates (the MESH and uploads): mm | cm | m. The page works in mm, as the image "
         "and every length typed; saving writes the mesh back in its unit")
      ->capture_default_str();
  add_laplacian_option(cmd, a->laplacian);
  cmd->add_option("--web-root", a->web_root, "Folder with the built page")->capture_default_str();
  cmd->add_option("--max-upload-mb", a->max_upload_mb, "Largest accepted upload")->capture_default_str();
  cmd->callback([a] {
    if (a->port < 0 || a->port > 65535) throw InputError(fmt::format("--port {} is outside 0..65535", a->port));
    editor::serve(*a);
  });
}

}  // namespace meshpde::cli
