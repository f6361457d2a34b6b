// Zip archives held in memory (libzip, in the component meshpde::medical): the editor's
// session files are one archive of named entries. Reading checks the declared sizes
// before anything is unpacked; entry names are only keys, never paths.
#pragma once

#include <cstddef>
#include <functional>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace meshpde {

/// Calls `visit(entry, bytes)` for each entry of the archive in its order (folders left
/// out), one unpacked at a time: a reader of many files (a DICOM series) holds one.
/// \throw InputError as read_zip_entries.
void for_each_zip_entry(const std::string& bytes, const std::string& name, std::size_t max_bytes,
                        const std::function<void(const std::string& entry, std::string data)>& visit);

/// The archive's entries (name -> bytes; folders left out). `name` is for messages.
/// \throw InputError naming the archive: not a zip archive, an entry that cannot be
///        unpacked, more than 100,000 entries or more than `max_bytes` unpacked in all.
std::map<std::string, std::string> read_zip_entries(const std::string& bytes, const std::string& name,
                                                    std::size_t max_bytes);

/// An archive of `entries` (name, bytes), each deflated, in this order.
/// \throw Error if libzip fails.
std::string write_zip(const std::vector<std::pair<std::string, std::string>>& entries);

}  // namespace meshpde
