// Hierarchy stream files.

#include <progiso/io/hierarchy_io.hpp>

#include <span>
#include <vector>

#include <progiso/io/detail/file_input.hpp>

namespace progiso {

hierarchy_stream read_hierarchy_stream(const std::filesystem::path& file,
                                       std::uint64_t max_records) {
  detail::input_file in(file, "hierarchy stream");
  const std::vector<char> bytes = in.read_all();
  try {
    return hierarchy_stream::decode(
        std::span<const std::byte>(reinterpret_cast<const std::byte*>(bytes.data()), bytes.size()),
        max_records);
  } catch (const error& e) {
    throw error(file.string() + ": " + e.what());
  }
}

}  // namespace progiso
