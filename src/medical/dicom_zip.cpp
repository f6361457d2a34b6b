// DICOM series uploaded as a .zip archive: unpacked with libzip into a private
// temporary folder (the entries' own names are never used as paths), then read as a folder.
#include <fmt/format.h>
#include <unistd.h>
#include <zip.h>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <memory>

#include "meshpde/core/errors.h"
#include "meshpde/io/dicom.h"

namespace meshpde {

namespace {

namespace fs = std::filesystem;

struct ArchiveCloser {
  void operator()(zip_t* z) const { zip_discard(z); }
};
struct EntryCloser {
  void operator()(zip_file_t* f) const { zip_fclose(f); }
};

}  // namespace

Volume read_dicom_zip(const std::string& bytes, const std::string& name, const std::string& choice,
                      std::size_t max_voxels, std::size_t max_bytes) {
  zip_error_t error;
  zip_error_init(&error);
  zip_source_t* source = zip_source_buffer_create(bytes.data(), bytes.size(), 0, &error);
  if (!source) throw InputError(fmt::format("{}: cannot read the archive ({})", name, zip_error_strerror(&error)));
  std::unique_ptr<zip_t, ArchiveCloser> archive(zip_open_from_source(source, ZIP_RDONLY, &error));
  if (!archive) {
    zip_source_free(source);
    const std::string why = zip_error_strerror(&error);
    zip_error_fini(&error);
    throw InputError(fmt::format("{}: not a zip archive ({})", name, why));
  }
  zip_error_fini(&error);
  const zip_int64_t entries = zip_get_num_entries(archive.get(), 0);
  if (entries < 0 || entries > 100000)
    throw InputError(fmt::format("{}: an archive of {} entries (100,000 at most)", name, entries));
  // Sizes first: the archive's declared total is checked before anything is unpacked.
  std::uint64_t total = 0;
  for (zip_int64_t k = 0; k < entries; ++k) {
    zip_stat_t st;
    if (zip_stat_index(archive.get(), static_cast<zip_uint64_t>(k), 0, &st) != 0)
      throw InputError(fmt::format("{}: entry {} cannot be read", name, k));
    if (st.valid & ZIP_STAT_SIZE) total += st.size;
    if (total > max_bytes)
      throw InputError(fmt::format("{}: unpacks to more than {} bytes, more than this reader takes", name, max_bytes));
  }
  static std::atomic<unsigned> serial{0};
  const fs::path dir = fs::temp_directory_path() / fmt::format("meshpde-dicom-{}-{}", ::getpid(), ++serial);
  struct RemoveAtExit {  // whatever happens, the unpacked files go
    fs::path path;
    ~RemoveAtExit() {
      std::error_code ec;
      fs::remove_all(path, ec);
    }
  } remove_at_exit{dir};
  fs::create_directories(dir);
  std::string buffer(1 << 16, '\0');
  int written = 0;
  for (zip_int64_t k = 0; k < entries; ++k) {
    zip_stat_t st;
    zip_stat_index(archive.get(), static_cast<zip_uint64_t>(k), 0, &st);
    const std::string entry = st.valid & ZIP_STAT_NAME ? st.name : fmt::format("entry {}", k);
    if (!entry.empty() && entry.back() == '/') continue;  // a folder
    std::unique_ptr<zip_file_t, EntryCloser> in(zip_fopen_index(archive.get(), static_cast<zip_uint64_t>(k), 0));
    if (!in) throw InputError(fmt::format("{}: {}: cannot unpack ({})", name, entry, zip_strerror(archive.get())));
    std::ofstream out(dir / fmt::format("{:06d}.dcm", k), std::ios::binary);
    std::uint64_t size = 0;
    for (;;) {
      const zip_int64_t n = zip_fread(in.get(), buffer.data(), buffer.size());
      if (n < 0) throw InputError(fmt::format("{}: {}: damaged ({})", name, entry, zip_file_strerror(in.get())));
      if (n == 0) break;
      size += static_cast<std::uint64_t>(n);
      if (size > st.size || size > max_bytes)
        throw InputError(fmt::format("{}: {}: unpacks to more than it declares", name, entry));
      out.write(buffer.data(), n);
    }
    if (!out) throw InputError(fmt::format("{}: cannot unpack {} (disk full?)", name, entry));
    ++written;
  }
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
