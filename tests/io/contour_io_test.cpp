// Tests for progiso/io/contour_io.hpp: the OBJ text and its exact round trip (open and closed
// polylines, isovalues), read_contour_obj's rejection of everything else, the SVG document
// (frame, one element per polyline, colours per isovalue, the embedded PNG decoded back to the
// image), dispatch by extension, and all-or-nothing writes.
#include <progiso/io/contour_io.hpp>

#include <gtest/gtest.h>

#include "support/io_test_helpers.hpp"
#include "support/scratch_dir.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <string>
#include <system_error>
#include <utility>
#include <vector>

#include <progiso/core/base/error.hpp>
#include <progiso/core/field/volume.hpp>
#include <progiso/io/image_io.hpp>

namespace {

namespace fs = std::filesystem;
using progiso::contour_set;
using progiso::polyline;
using progiso::volume;

class scratch_dir : public progiso::test::scratch_dir {
 public:
  scratch_dir() : progiso::test::scratch_dir("progiso-contour-io-test-") {}
};

std::string file_text(const fs::path& file) {
  std::string text(static_cast<std::size_t>(fs::file_size(file)), '\0');
  std::ifstream(file, std::ios::binary)
      .read(text.data(), static_cast<std::streamsize>(text.size()));
  return text;
}

void write_text(const fs::path& file, const std::string& bytes) {
  progiso::test::write_file(file, bytes);
}

template <class F>
std::string error_message(const fs::path& file, F&& f) {
  return progiso::test::error_message_naming(file, std::forward<F>(f), ":");
}

using progiso::test::contains;

std::size_t count(const std::string& haystack, const std::string& needle) {
  std::size_t n = 0;
  for (std::size_t at = haystack.find(needle); at != std::string::npos;
       at = haystack.find(needle, at + needle.size())) {
    ++n;
  }
  return n;
}

void expect_same(const contour_set& a, const contour_set& b) {
  ASSERT_EQ(a.vertices.size(), b.vertices.size());
  for (std::size_t i = 0; i < a.vertices.size(); ++i) {
    // Bitwise: shortest round-trip decimals must give back the very same doubles.
    EXPECT_EQ(a.vertices[i], b.vertices[i]) << "vertex " << i;
  }
  ASSERT_EQ(a.polylines.size(), b.polylines.size());
  for (std::size_t i = 0; i < a.polylines.size(); ++i) {
    EXPECT_EQ(a.polylines[i].vertices, b.polylines[i].vertices) << "polyline " << i;
    EXPECT_EQ(a.polylines[i].closed, b.polylines[i].closed) << "polyline " << i;
    EXPECT_EQ(a.polylines[i].isovalue, b.polylines[i].isovalue) << "polyline " << i;
  }
}

// A closed square around (1.5, 1.5) at isovalue 64, an open chain at 64, and an open chain
// and a closed triangle at 127.5; coordinates that need all 17 significant digits included.
contour_set sample_contours() {
  contour_set c;
  c.vertices = {{1.0, 0.5},       {2.5, 1.0},       {2.0, 2.5},    {0.5, 2.0},
                {0.1, 1.0 / 3.0}, {3.0, 2.0 / 3.0}, {1e-300, 4.0}, {-0.0, 5.25},
                {2.0, 3.5},       {3.0, 0.1 + 0.2}, {0.75, 3.0}};
  c.polylines = {polyline{{0, 1, 2, 3}, true, 64.0}, polyline{{4, 5}, false, 64.0},
                 polyline{{6, 7, 8}, false, 127.5}, polyline{{8, 9, 10}, true, 127.5}};
  return c;
}

/// A 4 x 3 u16 image with values 100 + 50 * (x + 4 y): range 100..650.
volume sample_image() {
  std::vector<std::byte> bytes(4 * 3 * 2);
  auto* samples = reinterpret_cast<std::uint16_t*>(bytes.data());
  for (int i = 0; i < 12; ++i) samples[i] = static_cast<std::uint16_t>(100 + 50 * i);
  return volume({4, 3, 1}, progiso::sample_type::u16, std::move(bytes));
}

/// RFC 4648 base64 decoding (no whitespace); nullopt-like empty result with ok = false on
/// malformed input.
std::pair<std::string, bool> base64_decode(const std::string& text) {
  const std::string alphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  if (text.size() % 4 != 0) return {{}, false};
  std::string out;
  for (std::size_t i = 0; i < text.size(); i += 4) {
    std::uint32_t group = 0;
    int padding = 0;
    for (std::size_t k = 0; k < 4; ++k) {
      const char c = text[i + k];
      std::uint32_t value = 0;
      if (c == '=' && i + 4 == text.size() && k >= 2) {
        ++padding;
      } else {
        const std::size_t at = alphabet.find(c);
        if (at == std::string::npos || padding > 0) return {{}, false};
        value = static_cast<std::uint32_t>(at);
      }
      group = (group << 6) | value;
    }
    out += static_cast<char>((group >> 16) & 0xffu);
    if (padding < 2) out += static_cast<char>((group >> 8) & 0xffu);
    if (padding < 1) out += static_cast<char>(group & 0xffu);
  }
  return {out, true};
}

/// The value of attribute `name` in the first element that starts with `element`.
std::string attribute(const std::string& svg, const std::string& element, const std::string& name) {
  const std::size_t start = svg.find(element);
  if (start == std::string::npos) return {};
  const std::size_t end = svg.find('>', start);
  const std::size_t at = svg.find(" " + name + "=\"", start);
  if (at == std::string::npos || at > end) return {};
  const std::size_t value = at + name.size() + 3;
  return svg.substr(value, svg.find('"', value) - value);
}

// =============================================================================================
// OBJ.

TEST(ContourIo, obj_round_trip_preserves_vertices_polylines_and_isovalues_exactly) {
  const scratch_dir dir;
  const contour_set c = sample_contours();
  progiso::write_contour_obj(dir / "c.obj", c);
  expect_same(progiso::read_contour_obj(dir / "c.obj"), c);
  EXPECT_TRUE(std::signbit(progiso::read_contour_obj(dir / "c.obj").vertices[7][0]));
}

TEST(ContourIo, obj_lists_vertices_then_one_line_per_polyline_closing_loops_by_repetition) {
  const scratch_dir dir;
  contour_set c;
  c.vertices = {{0.0, 0.5}, {1.5, 0.0}, {1.0, 1.0}, {2.0, 2.25}};
  c.polylines = {polyline{{0, 1, 2}, true, 0.5}, polyline{{2, 3}, false, 0.5},
                 polyline{{3, 1}, false, -7.0}, polyline{{0, 3, 2}, true, 0.5}};
  progiso::write_contour_obj(dir / "c.obj", c);
  EXPECT_EQ(file_text(dir / "c.obj"),
            "# generated by progiso: isocontours, 4 vertices, 4 polylines\n"
            "v 0 0.5 0\nv 1.5 0 0\nv 1 1 0\nv 2 2.25 0\n"
            "# isovalue 0.5\nl 1 2 3 1\nl 3 4\n"
            "# isovalue -7\nl 4 2\n"
            "# isovalue 0.5\nl 1 4 3 1\n");
}

TEST(ContourIo, empty_contour_set_round_trips_through_obj) {
  const scratch_dir dir;
  progiso::write_contour_obj(dir / "e.obj", contour_set{});
  EXPECT_EQ(file_text(dir / "e.obj"),
            "# generated by progiso: isocontours, 0 vertices, 0 polylines\n");
  const contour_set r = progiso::read_contour_obj(dir / "e.obj");
  EXPECT_TRUE(r.vertices.empty());
  EXPECT_TRUE(r.empty());
}

TEST(ContourIo, read_contour_obj_accepts_crlf_missing_z_groups_and_comments) {
  const scratch_dir dir;
  write_text(dir / "c.obj",
             "# from elsewhere\r\no contour\r\nv 0 0\r\nv 1 0 0\r\n\r\nv 1 1 0.0\r\ng a\r\n"
             "#isovalue 3.5\r\nl 1 2 3 1\r\ns off\r\n# isovalue 4\r\nl 3 2\r\nl 2\r\n");
  const contour_set r = progiso::read_contour_obj(dir / "c.obj");
  ASSERT_EQ(r.vertices.size(), 3u);
  EXPECT_EQ(r.vertices[2], (progiso::vec2{1.0, 1.0}));
  ASSERT_EQ(r.polylines.size(), 3u);
  EXPECT_EQ(r.polylines[0].vertices, (std::vector<std::uint32_t>{0, 1, 2}));
  EXPECT_TRUE(r.polylines[0].closed);
  EXPECT_EQ(r.polylines[0].isovalue, 3.5);
  EXPECT_EQ(r.polylines[1].vertices, (std::vector<std::uint32_t>{2, 1}));
  EXPECT_FALSE(r.polylines[1].closed);
  EXPECT_EQ(r.polylines[1].isovalue, 4.0);
  EXPECT_EQ(r.polylines[2].vertices, (std::vector<std::uint32_t>{1}));
}

TEST(ContourIo, read_contour_obj_rejects_other_elements_bad_numbers_and_bad_indices) {
  const scratch_dir dir;
  const std::string three = "v 0 0 0\nv 1 0 0\nv 1 1 0\n";
  const std::vector<std::pair<std::string, std::string>> cases = {
      {three + "f 1 2 3\n", ":4: expected only v and l lines in a contour OBJ file, found \"f\""},
      {three + "vt 0 1\n", "found \"vt\""},
      {"v 0 0 1\n", ":1: expected a 2D contour vertex with z = 0, found z = \"1\""},
      {"v 0\n", ":1: expected \"v x y 0\" with decimal numbers, found \"v 0\""},
      {"v 0 zero 0\n", "expected \"v x y 0\""},
      {"v 0 0 0 1\n", "expected \"v x y 0\""},
      {"v 1e999 0 0\n", "expected \"v x y 0\""},
      {three + "l 1 4\n", ":4: vertex index 4 is out of range (expected 1 to 3"},
      {three + "l 0 1\n", "vertex index 0 is out of range"},
      {three + "l 1 -1\n", "expected a positive vertex index, found \"-1\""},
      {three + "l 1/1 2/2\n", "expected a positive vertex index, found \"1/1\""},
      {three + "l\n", ":4: expected \"l\" and at least one vertex index"},
      {"l 1 2\n" + three, ":1: vertex index 1 is out of range (expected 1 to 0"},
      {"# isovalue high\n", ":1: expected \"# isovalue\" and a number"},
  };
  for (const auto& [text, fragment] : cases) {
    const fs::path file = dir / "bad.obj";
    write_text(file, text);
    const std::string message = error_message(file, [&] { (void)progiso::read_contour_obj(file); });
    EXPECT_TRUE(contains(message, fragment)) << message << "\n  expected: " << fragment;
  }
  const fs::path missing = dir / "missing.obj";
  EXPECT_TRUE(contains(error_message(missing, [&] { (void)progiso::read_contour_obj(missing); }),
                       "cannot open OBJ file"));
}

// =============================================================================================
// SVG.

TEST(ContourIo, svg_has_one_polyline_or_polygon_per_contour_grouped_by_isovalue) {
  const scratch_dir dir;
  const contour_set c = sample_contours();
  progiso::write_contour_svg(dir / "c.svg", c);
  const std::string svg = file_text(dir / "c.svg");
  EXPECT_EQ(svg.rfind("<svg ", 0), 0u);
  EXPECT_TRUE(svg.ends_with("</svg>\n"));
  EXPECT_EQ(count(svg, "<svg"), 1u);
  EXPECT_EQ(count(svg, "</svg>"), 1u);
  EXPECT_TRUE(contains(svg, "xmlns=\"http://www.w3.org/2000/svg\""));
  EXPECT_EQ(count(svg, "<title>"), 1u);
  EXPECT_TRUE(
      contains(svg, "<title>progiso isocontours: 4 polylines, isovalues 64, 127.5</title>"));
  // Open chains as polylines, loops as polygons, one each.
  EXPECT_EQ(count(svg, "<polyline "), 2u);
  EXPECT_EQ(count(svg, "<polygon "), 2u);
  EXPECT_EQ(count(svg, "<g "), 2u);
  EXPECT_EQ(count(svg, "</g>"), 2u);
  EXPECT_EQ(count(svg, "\"/>"), 4u);  // every polyline and polygon element is closed
  EXPECT_TRUE(contains(svg, "<g data-isovalue=\"64\" fill=\"none\" stroke=\"#ffd400\""));
  EXPECT_TRUE(contains(svg, "<g data-isovalue=\"127.5\" fill=\"none\""));
  EXPECT_TRUE(contains(svg, "<polygon points=\"1,0.5 2.5,1 2,2.5 0.5,2\"/>"));
  EXPECT_FALSE(contains(svg, "data:image"));
  EXPECT_FALSE(contains(svg, "<image"));
}

TEST(ContourIo, svg_gives_each_isovalue_its_own_colour_in_ascending_order) {
  const scratch_dir dir;
  contour_set c;
  c.vertices = {{0, 0}, {1, 1}};
  for (double w : {30.0, 10.0, 20.0, 10.0}) c.polylines.push_back(polyline{{0, 1}, false, w});
  progiso::write_contour_svg(dir / "c.svg", c);
  const std::string svg = file_text(dir / "c.svg");
  const std::size_t g10 = svg.find("data-isovalue=\"10\"");
  const std::size_t g20 = svg.find("data-isovalue=\"20\"");
  const std::size_t g30 = svg.find("data-isovalue=\"30\"");
  ASSERT_NE(g10, std::string::npos);
  EXPECT_LT(g10, g20);
  EXPECT_LT(g20, g30);
  EXPECT_EQ(count(svg, "data-isovalue="), 3u);
  std::vector<std::string> colours;
  for (const std::size_t at : {g10, g20, g30}) {
    colours.push_back(attribute(svg.substr(at - 3), "<g ", "stroke"));
  }
  EXPECT_EQ(colours[0], "#ffd400");
  EXPECT_NE(colours[0], colours[1]);
  EXPECT_NE(colours[1], colours[2]);
  EXPECT_NE(colours[0], colours[2]);
}

TEST(ContourIo, svg_view_box_is_the_image_sample_area_with_pixel_centres_on_integers) {
  const scratch_dir dir;
  const volume image = sample_image();
  progiso::write_contour_svg(dir / "c.svg", sample_contours(), &image);
  const std::string svg = file_text(dir / "c.svg");
  EXPECT_EQ(attribute(svg, "<svg", "viewBox"), "-0.5 -0.5 4 3");
  EXPECT_EQ(attribute(svg, "<image", "x"), "-0.5");
  EXPECT_EQ(attribute(svg, "<image", "y"), "-0.5");
  EXPECT_EQ(attribute(svg, "<image", "width"), "4");
  EXPECT_EQ(attribute(svg, "<image", "height"), "3");
  EXPECT_EQ(attribute(svg, "<image", "style"), "image-rendering:pixelated");
  // Scaled up so that the longer side is 512 px; lines 1.5 px wide at that size.
  EXPECT_EQ(attribute(svg, "<svg", "width"), "512");
  EXPECT_EQ(attribute(svg, "<svg", "height"), "384");
  EXPECT_EQ(std::stod(attribute(svg, "<g ", "stroke-width")), 1.5 / 128.0);
  // The image is drawn first, the contours over it.
  EXPECT_LT(svg.find("<image"), svg.find("<polygon"));
}

TEST(ContourIo, svg_embedded_png_decodes_to_the_image_mapped_onto_0_to_255) {
  const scratch_dir dir;
  const volume image = sample_image();
  progiso::write_contour_svg(dir / "c.svg", sample_contours(), &image);
  const std::string svg = file_text(dir / "c.svg");
  const std::string href = attribute(svg, "<image", "xlink:href");
  const std::string prefix = "data:image/png;base64,";
  ASSERT_EQ(href.rfind(prefix, 0), 0u) << href.substr(0, 40);
  const auto [png, ok] = base64_decode(href.substr(prefix.size()));
  ASSERT_TRUE(ok);
  ASSERT_GE(png.size(), 8u);
  EXPECT_EQ(png.substr(0, 8), std::string("\x89PNG\r\n\x1a\n"));

  write_text(dir / "embedded.png", png);
  const volume decoded = progiso::read_png(dir / "embedded.png");
  EXPECT_EQ(decoded.dims(), image.dims());
  EXPECT_EQ(decoded.type(), progiso::sample_type::u8);
  for (std::size_t i = 0; i < image.voxel_count(); ++i) {
    EXPECT_EQ(decoded.at(i), std::round((image.at(i) - 100.0) * 255.0 / 550.0)) << i;
  }
}

TEST(ContourIo, svg_of_a_constant_image_embeds_black) {
  const scratch_dir dir;
  const volume image({2, 2, 1}, progiso::sample_type::u8, std::vector<std::byte>(4, std::byte{9}));
  progiso::write_contour_svg(dir / "c.svg", contour_set{}, &image);
  const std::string href = attribute(file_text(dir / "c.svg"), "<image", "xlink:href");
  const auto [png, ok] = base64_decode(href.substr(href.find(',') + 1));
  ASSERT_TRUE(ok);
  write_text(dir / "embedded.png", png);
  const volume decoded = progiso::read_png(dir / "embedded.png");
  EXPECT_EQ(decoded.value_range(), (std::array<double, 2>{0, 0}));
}

TEST(ContourIo, svg_view_box_follows_image_spacing_and_origin) {
  const scratch_dir dir;
  const volume image({4, 2, 1}, progiso::sample_type::u8, std::vector<std::byte>(8),
                     {0.5, 2.0, 1.0}, {10.0, -4.0, 0.0});
  progiso::write_contour_svg(dir / "c.svg", contour_set{}, &image);
  const std::string svg = file_text(dir / "c.svg");
  EXPECT_EQ(attribute(svg, "<svg", "viewBox"), "9.75 -5 2 4");
  EXPECT_EQ(attribute(svg, "<image", "x"), "9.75");
  EXPECT_EQ(attribute(svg, "<image", "height"), "4");
}

TEST(ContourIo, svg_without_image_frames_the_contours_bounding_box) {
  const scratch_dir dir;
  contour_set c;
  c.vertices = {{2.0, 10.0}, {6.0, 11.5}, {4.0, 13.0}};
  c.polylines = {polyline{{0, 1, 2}, true, 1.0}};
  progiso::write_contour_svg(dir / "c.svg", c);
  EXPECT_EQ(attribute(file_text(dir / "c.svg"), "<svg", "viewBox"), "1.5 9.5 5 4");

  progiso::write_contour_svg(dir / "e.svg", contour_set{});
  const std::string empty = file_text(dir / "e.svg");
  EXPECT_EQ(attribute(empty, "<svg", "viewBox"), "0 0 1 1");
  EXPECT_EQ(count(empty, "<g "), 0u);
  EXPECT_TRUE(contains(empty, "<title>progiso isocontours: 0 polylines</title>"));
}

// =============================================================================================
// Dispatch and all-or-nothing writes.

TEST(ContourIo, write_contours_picks_the_format_by_extension_in_any_case) {
  const scratch_dir dir;
  const contour_set c = sample_contours();
  const volume image = sample_image();
  progiso::write_contours(dir / "a.OBJ", c, &image);
  progiso::write_contours(dir / "b.Svg", c, &image);
  expect_same(progiso::read_contour_obj(dir / "a.OBJ"), c);
  EXPECT_EQ(file_text(dir / "a.OBJ").rfind("# generated by progiso", 0), 0u);
  const std::string svg = file_text(dir / "b.Svg");
  EXPECT_EQ(svg.rfind("<svg ", 0), 0u);
  EXPECT_TRUE(contains(svg, "data:image/png;base64,"));
}

TEST(ContourIo, write_contours_rejects_an_unknown_extension_and_creates_nothing) {
  const scratch_dir dir;
  const fs::path file = dir / "c.png";
  const std::string message =
      error_message(file, [&] { progiso::write_contours(file, sample_contours()); });
  EXPECT_EQ(message, file.string() + ": unknown contour format \".png\" (expected .obj or .svg)");
  EXPECT_TRUE(dir.entries().empty());
}

TEST(ContourIo, write_into_a_missing_directory_throws_and_leaves_no_file) {
  const scratch_dir dir;
  const volume image = sample_image();
  for (const char* name : {"c.obj", "c.svg"}) {
    const fs::path target = dir / "missing" / name;
    const std::string message =
        error_message(target, [&] { progiso::write_contours(target, sample_contours(), &image); });
    EXPECT_TRUE(contains(message, "cannot create the file in")) << message;
    EXPECT_FALSE(fs::exists(target));
  }
  EXPECT_TRUE(dir.entries().empty());
}

TEST(ContourIo, overwriting_replaces_the_file_and_leaves_no_temporary) {
  const scratch_dir dir;
  write_text(dir / "c.obj", "old contents\n");
  write_text(dir / "c.svg", "old contents\n");
  const contour_set c = sample_contours();
  progiso::write_contours(dir / "c.obj", c);
  progiso::write_contours(dir / "c.svg", c);
  expect_same(progiso::read_contour_obj(dir / "c.obj"), c);
  EXPECT_EQ(file_text(dir / "c.svg").rfind("<svg ", 0), 0u);
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"c.obj", "c.svg"}));
}

TEST(ContourIo, a_directory_in_the_targets_place_is_refused_before_writing) {
  const scratch_dir dir;
  fs::create_directory(dir / "c.svg");
  write_text(dir / "c.svg" / "keep", "x");
  const std::string message = error_message(
      dir / "c.svg", [&] { progiso::write_contours(dir / "c.svg", sample_contours()); });
  EXPECT_TRUE(contains(message, "found a directory")) << message;
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"c.svg"}));
}

TEST(ContourIo, failed_rename_leaves_the_target_untouched_and_removes_the_temporary) {
  const scratch_dir dir;
  // A non-empty directory appears in the target's place while the file is being written: the
  // temporary is complete, the rename fails.
  const progiso::contour_set c = sample_contours();
  std::vector<double> isovalues;
  for (const auto& p : c.polylines) isovalues.push_back(p.isovalue);
  const std::string message = error_message(dir / "c.obj", [&] {
    progiso::contour_writer w(dir / "c.obj", isovalues);
    w.add(c);
    fs::create_directory(dir / "c.obj");
    write_text(dir / "c.obj" / "keep", "x");
    w.commit();
  });
  EXPECT_TRUE(contains(message, "cannot move the finished temporary file onto it")) << message;
  EXPECT_EQ(dir.entries(), (std::vector<std::string>{"c.obj"}));
  EXPECT_TRUE(fs::is_directory(dir / "c.obj"));
  EXPECT_EQ(file_text(dir / "c.obj" / "keep"), "x");
}

}  // namespace
