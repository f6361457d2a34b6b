// apps/selection.h: selection specs and vertex lists.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "meshpde/apps/selection.h"
#include "meshpde/core/errors.h"
#include "meshpde/core/warnings.h"
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

// A point "@X,Y,Z" far from its nearest vertex (more than kFarPointEdges of the longest
// edge there) is warned about, naming the spec and the vertex; a point on or near the
// surface is not. Collectors nest and take what is given while they are innermost.
TEST(Selection, AFarPointIsWarnedAboutAndANearOneIsNot) {
  const Mesh m = make(plane_grid(10, 10));  // the unit square, edges 0.1 (diagonals 0.14)
  WarningCollector outer;
  EXPECT_EQ(parse_vertex_spec(m, "@0.52,0.49,0.05"), 60);            // just off the surface
  EXPECT_EQ(select_vertices(m, "rings:@0.5,0.5,0.3:1").size(), 7u);  // 0.3 above: about twice the longest edge
  EXPECT_TRUE(outer.take().empty());
  {
    WarningCollector inner;
    EXPECT_EQ(parse_vertex_spec(m, "@0.5,0.5,2"), 60);
    const std::vector<std::string> got = inner.take();
    ASSERT_EQ(got.size(), 1u);
    EXPECT_NE(got[0].find("'@0.5,0.5,2'"), std::string::npos) << got[0];
    EXPECT_NE(got[0].find("nearest vertex 60"), std::string::npos) << got[0];
    EXPECT_NE(got[0].find("lies 2 "), std::string::npos) << got[0];
  }
  // Through selections, after the inner collector is gone: the outer takes them.
  EXPECT_EQ(select_vertices(m, "radius:@5,5,0:0.11").size(), 3u);  // the corner (1, 1) and its two neighbours
  EXPECT_EQ(select_vertices(m, "rings:@-3,0,0:0"), (std::vector<int>{0}));
  const std::vector<std::string> got = outer.take();
  ASSERT_EQ(got.size(), 2u);
  EXPECT_NE(got[0].find("'@5,5,0'"), std::string::npos) << got[0];
  EXPECT_NE(got[1].find("'@-3,0,0'"), std::string::npos) << got[1];
  // Plain indices never warn.
  EXPECT_EQ(parse_vertex_spec(m, "7"), 7);
  EXPECT_TRUE(outer.take().empty());
}
