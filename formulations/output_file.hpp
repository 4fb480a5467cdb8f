// One output file of a tool (a JSON record, a CSV table, a report page), written whole or
// not at all. `kneedyn run`'s three files are a set and are published together instead
// (run_output.hpp); these are single files that stand alone.
#pragma once

#include <filesystem>
#include <string>

namespace kneedyn {

// The nearest existing ancestor of `path` (itself excluded): where the missing levels of
// `path` would be created. A relative path whose first level is missing ends at ".".
std::filesystem::path NearestExistingAncestor(const std::filesystem::path& path);

// Before a long computation: `path` could be written, i.e. it is new or a regular file (not a
// directory, device, FIFO or symbolic link) and its
// nearest existing ancestor is a directory this process may write in (the missing levels
// between them are created by WriteOutputFile). Leaves nothing behind (it makes and removes
// one probe directory there, the test that also holds for root and /proc). Throws InputError
// "<function>(): <option> = '<path>': <rule>", so that a bad path is refused before the
// work rather than after it.
void CheckOutputFile(const std::string& function, const std::string& option, const std::string& path);

// The same for a directory a tool writes its files into (--out of kneedyn sweep, of the
// catalog): `dir` is a directory this process can create files in, or does not exist and
// its nearest existing ancestor is one. Leaves nothing behind.
void CheckOutputDirectoryWritable(const std::string& function, const std::string& option, const std::string& dir);

// Writes `text` to "<path>.tmp" beside `path` (creating missing parent directories), then
// renames it over `path`: a reader sees the previous file or the new one, never a part.
// Throws InputError as CheckOutputFile, with the system's reason; the temporary file is
// removed when the write fails.
void WriteOutputFile(const std::string& function, const std::string& option, const std::string& path,
                     const std::string& text);

}  // namespace kneedyn
