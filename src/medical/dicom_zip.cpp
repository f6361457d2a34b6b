// DICOM series uploaded as a .zip archive: unpacked (io/zip_archive.h) into a private
// temporary folder (the entries' own names are never used as paths), then read as a folder.
#include <fmt/format.h>

#include <filesystem>
#include <fstream>

#include "meshpde/core/errors.h"
#include "meshpde/io/dicom.h"
#include "meshpde/io/mesh_io.h"
#include "meshpde/io/zip_archive.h"

namespace meshpde {

namespace fs = std::filesystem;

Volume read_dicom_zip(const std::string& bytes, const std::string& name, const std::string& choice,
                      std::size_t max_voxels, std::size_t max_bytes) {
  const TemporaryPath unpacked("meshpde-dicom");  // whatever happens, the unpacked files go
  const fs::path& dir = unpacked.path();
  fs::create_directories(dir);
  // One entry unpacked at a time (io/zip_archive.h), each written under a name of ours.
  int written = 0;
  for_each_zip_entry(bytes, name, max_bytes, [&](const std::string& entry, std::string data) {
    std::ofstream out(dir / fmt::format("{:06d}.dcm", written), std::ios::binary);
    out.write(data.data(), static_cast<std::streamsize>(data.size()));
    if (!out) throw InputError(fmt::format("{}: cannot unpack {} (disk full?)", name, entry));
    ++written;
  });
  if (written == 0) throw InputError(fmt::format("{}: the archive holds no files", name));
  try {
    Volume v = read_dicom_series(dir, choice, max_voxels);
    v.name = name;
    return v;
  } catch (const InputError& e) {
    // Name the archive, not the temporary folder.
    std::string what = e.what();
    for (std::size_t at; (at = what.find(dir.string())) != std::string::npos;)
      what.replace(at, dir.string().size(), name);
    throw InputError(what);
  }
}

}  // namespace meshpde
