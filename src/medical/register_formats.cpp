// Registers the medical component's file formats with the core library's registry
// (io/file_formats.h) before main() runs, so read_mesh, write_mesh and read_volume know
// them in every program that links meshpde::medical.
//
// A static library's object file is linked only when something refers to it, and a
// program that reads files through read_mesh refers to nothing here. So the component
// asks every program that links it to keep this symbol (CMake: INTERFACE link option
// --undefined=meshpde_medical_formats), which keeps this file and its registrar.
#include "meshpde/core/errors.h"
#include "meshpde/io/dicom.h"
#include "meshpde/io/file_formats.h"
#include "meshpde/io/medical_io.h"
#include "volume_formats.h"

extern "C" {
// The symbol the link option names; its value is never read.
extern const int meshpde_medical_formats;
const int meshpde_medical_formats = 1;
}

namespace meshpde {
namespace {

MeshFileFormat vtk_format(const char* name, const char* extension) {
  MeshFileFormat f;
  f.name = name;
  f.extensions = {extension};
  f.read = [](const std::string& bytes, const std::string& ext, const std::string& file) {
    return read_vtk_mesh_from_memory(bytes, ext.substr(1), file);
  };
  f.write = [](const MeshData& data, const std::string& ext, const WriteOptions&) {
    return write_vtk_mesh_to_memory(data, ext.substr(1));  // always binary
  };
  f.keeps_vertex_fields = f.keeps_data_arrays = f.keeps_field_data = true;
  return f;
}

VolumeFileFormat volume_format(const char* name, std::vector<std::string> suffixes,
                               Volume (*read)(const std::filesystem::path&, std::size_t)) {
  VolumeFileFormat f;
  f.name = name;
  f.suffixes = std::move(suffixes);
  f.read = [read](const std::filesystem::path& path, const VolumeReadOptions& options) {
    return read(path, options.max_voxels);
  };
  return f;
}

struct Registrar {
  Registrar() {
    register_mesh_format(vtk_format("VTK XML PolyData", ".vtp"));
    register_mesh_format(vtk_format("legacy VTK PolyData", ".vtk"));
    register_volume_format(
        volume_format("MetaImage", {".mha", ".mhd"},
                      [](const std::filesystem::path& p, std::size_t n) { return detail::read_metaimage(p, n); }));
    register_volume_format(
        volume_format("NIfTI-1", {".nii", ".nii.gz"},
                      [](const std::filesystem::path& p, std::size_t n) { return detail::read_nifti(p, n); }));
    register_volume_format(volume_format("NRRD", {".nrrd", ".nhdr"}, detail::read_nrrd));
    VolumeFileFormat dicom;
    dicom.name = "DICOM series";  // no suffix: .dcm files are recognized, as folders are
    dicom.recognizes = [](const std::filesystem::path& path) { return is_dicom_path(path); };
    dicom.read = [](const std::filesystem::path& path, const VolumeReadOptions& options) {
      return read_dicom_series(path, options.series, options.max_voxels);
    };
    register_volume_format(std::move(dicom));
  }
};

const Registrar registrar;

}  // namespace
}  // namespace meshpde
