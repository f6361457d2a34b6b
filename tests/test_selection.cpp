// apps/selection.h: selection specs and vertex lists.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "meshpde/apps/selection.h"
#include "meshpde/core/errors.h"
#include "meshpde/mesh/generators.h"
#include "test_support.h"

using namespace meshpde;
using test::error_of;
using test::make;

TEST(Selection, EveryKindAndClearErrors) {
  const Mesh m = make(plane_grid(10, 10));
  EXPECT_EQ(select_vertices(m, "boundary").size(), 40u);
  EXPECT_EQ(select_vertices(m, "all").size(), 121u);
  EXPECT_EQ(select_vertices(m, "rings:60:1").size(), 7u);              // interior vertex of the grid: valence 6
  EXPECT_EQ(select_vertices(m, "halfspace:1,0,0:0.25").size(), 33u);   // x <= 0.25: 3 columns of 11
  EXPECT_EQ(select_vertices(m, "radius:@0.5,0.5,0:0.11").size(), 5u);  // centre and its 4 axis neighbours
  VertexFields fields{{"h", m.positions().col(1)}};
  EXPECT_EQ(select_vertices(m, "field:h>0.95", fields).size(), 11u);
  EXPECT_EQ(select_vertices(m, std::vector<std::string>{"field:h>0.95", "field:h<0.05"}, fields).size(), 22u);
  const auto path = test::scratch_path("selection.txt");
  { std::ofstream(path) << "# two vertices\n3, 4\n4\n"; }
  EXPECT_EQ(select_vertices(m, "file:" + path.string()), (std::vector<int>{3, 4}));
  { std::ofstream(path) << "3\n999\n"; }
  try {
    select_vertices(m, "file:" + path.string());
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("line 2"), std::string::npos) << e.what();
  }
  EXPECT_THROW(select_vertices(m, "rings:5"), InputError);
  EXPECT_THROW(select_vertices(m, "field:nope>1"), InputError);
  EXPECT_THROW(select_vertices(m, "sphere:1"), InputError);
}

TEST(Parsers, VertexListsTakeCommasSpacesAndComments) {
  const Mesh m = make(plane_grid(4, 4));
  EXPECT_EQ(parse_vertex_list(m, "# head\n1, 2 3\n\n24\n", "s.txt"), (std::vector<int>{1, 2, 3, 24}));
  EXPECT_NE(error_of([&] { parse_vertex_list(m, "1\n2 x\n", "s.txt"); }).find("s.txt: line 2"), std::string::npos);
  EXPECT_NE(error_of([&] { parse_vertex_list(m, "25\n", "s.txt"); }).find("does not exist"), std::string::npos);
  EXPECT_TRUE(parse_vertex_list(m, "", "s.txt").empty());
}
