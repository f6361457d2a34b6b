#include "meshpde/io/zip_archive.h"

#include <fmt/format.h>
#include <zip.h>

#include <algorithm>
#include <memory>

#include "meshpde/core/errors.h"

namespace meshpde {

namespace {

struct ArchiveDiscard {
  void operator()(zip_t* z) const { zip_discard(z); }
};
struct EntryClose {
  void operator()(zip_file_t* f) const { zip_fclose(f); }
};

}  // namespace

void for_each_zip_entry(const std::string& bytes, const std::string& name, std::size_t max_bytes,
                        const std::function<void(const std::string& entry, std::string data)>& visit) {
  zip_error_t error;
  zip_error_init(&error);
  zip_source_t* source = zip_source_buffer_create(bytes.data(), bytes.size(), 0, &error);
  if (!source) {
    const std::string why = zip_error_strerror(&error);
    zip_error_fini(&error);
    throw InputError(fmt::format("{}: cannot read the archive ({})", name, why));
  }
  std::unique_ptr<zip_t, ArchiveDiscard> archive(zip_open_from_source(source, ZIP_RDONLY, &error));
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
  // Sizes first: the declared total is checked before anything is unpacked.
  std::uint64_t total = 0;
  for (zip_int64_t k = 0; k < entries; ++k) {
    zip_stat_t st;
    if (zip_stat_index(archive.get(), static_cast<zip_uint64_t>(k), 0, &st) != 0 || !(st.valid & ZIP_STAT_SIZE))
      throw InputError(fmt::format("{}: entry {} cannot be read", name, k));
    total += st.size;
    if (total > max_bytes)
      throw InputError(fmt::format("{}: unpacks to more than {} bytes, more than this reader takes", name, max_bytes));
  }
  for (zip_int64_t k = 0; k < entries; ++k) {
    zip_stat_t st;
    zip_stat_index(archive.get(), static_cast<zip_uint64_t>(k), 0, &st);
    const std::string entry = st.valid & ZIP_STAT_NAME ? st.name : fmt::format("entry {}", k);
    if (!entry.empty() && entry.back() == '/') continue;  // a folder
    std::unique_ptr<zip_file_t, EntryClose> in(zip_fopen_index(archive.get(), static_cast<zip_uint64_t>(k), 0));
    if (!in) throw InputError(fmt::format("{}: {}: cannot unpack ({})", name, entry, zip_strerror(archive.get())));
    std::string data(static_cast<std::size_t>(st.size), '\0');
    std::size_t got = 0;
    while (got < data.size()) {
      const zip_int64_t n = zip_fread(in.get(), data.data() + got, data.size() - got);
      if (n <= 0) break;
      got += static_cast<std::size_t>(n);
    }
    // A declared size the data do not fill, more data than declared, or a failed
    // checksum: a damaged archive.
    char extra = 0;
    if (got != data.size() || zip_fread(in.get(), &extra, 1) != 0)
      throw InputError(fmt::format("{}: {}: the entry is damaged ({})", name, entry, zip_file_strerror(in.get())));
    visit(entry, std::move(data));
  }
}

std::map<std::string, std::string> read_zip_entries(const std::string& bytes, const std::string& name,
                                                    std::size_t max_bytes) {
  std::map<std::string, std::string> out;
  for_each_zip_entry(bytes, name, max_bytes,
                     [&](const std::string& entry, std::string data) { out[entry] = std::move(data); });
  return out;
}

std::string write_zip(const std::vector<std::pair<std::string, std::string>>& entries) {
  zip_error_t error;
  zip_error_init(&error);
  // An archive built in a growing memory buffer, which zip_close() fills.
  zip_source_t* buffer = zip_source_buffer_create(nullptr, 0, 0, &error);
  if (!buffer) throw Error(fmt::format("zip: {}", zip_error_strerror(&error)));
  zip_source_keep(buffer);  // ours after the archive closes
  struct SourceFree {
    void operator()(zip_source_t* s) const { zip_source_free(s); }
  };
  std::unique_ptr<zip_source_t, SourceFree> keep(buffer);
  zip_t* z = zip_open_from_source(buffer, ZIP_TRUNCATE, &error);
  if (!z) {
    const std::string why = zip_error_strerror(&error);
    zip_error_fini(&error);
    throw Error(fmt::format("zip: {}", why));
  }
  zip_error_fini(&error);
  for (const auto& [name, data] : entries) {
    zip_source_t* s = zip_source_buffer(z, data.data(), data.size(), 0);  // read at zip_close()
    if (!s || zip_file_add(z, name.c_str(), s, ZIP_FL_ENC_UTF_8 | ZIP_FL_OVERWRITE) < 0) {
      if (s) zip_source_free(s);
      const std::string why = zip_strerror(z);
      zip_discard(z);
      throw Error(fmt::format("zip: {}: {}", name, why));
    }
  }
  if (zip_close(z) != 0) {
    const std::string why = zip_strerror(z);
    zip_discard(z);
    throw Error(fmt::format("zip: {}", why));
  }
  // The archive is the buffer's contents now.
  if (zip_source_open(buffer) != 0) throw Error("zip: cannot read the archive written");
  zip_source_seek(buffer, 0, SEEK_END);
  const zip_int64_t size = zip_source_tell(buffer);
  zip_source_seek(buffer, 0, SEEK_SET);
  std::string out(static_cast<std::size_t>(std::max<zip_int64_t>(size, 0)), '\0');
  const zip_int64_t got = zip_source_read(buffer, out.data(), out.size());
  zip_source_close(buffer);
  if (size < 0 || got != size) throw Error("zip: cannot read the archive written");
  return out;
}

}  // namespace meshpde
