// Tests of core/enum_names.hpp: one {enum, name} table gives parse, name and the names list.
#include <doctest/doctest.h>

#include <string>
#include <vector>

#include "core/enum_names.hpp"
#include "core/equilibrium.hpp"
#include "core/linear_solver.hpp"

using namespace tetfsi;

namespace {

enum class Colour { Red, Green, Blue, Unnamed };
constexpr EnumNames<Colour, 3> k_colours{
    "colour", {{{Colour::Red, "red"}, {Colour::Green, "green"}, {Colour::Blue, "blue"}}}};

std::string input_error(const std::string& name) {
  try {
    k_colours.parse(name);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST_SUITE("unit") {
  TEST_CASE("EnumNames: parse and name are inverse, names keep the table's order") {
    for (Colour c : {Colour::Red, Colour::Green, Colour::Blue})
      CHECK(k_colours.parse(k_colours.name(c)) == c);
    CHECK(k_colours.names() == std::vector<std::string>{"red", "green", "blue"});
    CHECK(k_colours.contains("green"));
    CHECK_FALSE(k_colours.contains("Green"));  // names are case-sensitive
    // The table is usable at compile time.
    static_assert(k_colours.table[1].value == Colour::Green);
  }

  TEST_CASE("EnumNames: an unknown name is a one-line InputError listing the valid ones") {
    CHECK(input_error("purple") == "unknown colour 'purple': use red, green or blue");
    CHECK(input_error("") == "unknown colour '': use red, green or blue");
    CHECK(or_list({"a"}) == "a");
    CHECK(or_list({"a", "b"}) == "a or b");
    CHECK(or_list({}) == "");
  }

  TEST_CASE("EnumNames: naming a value the table lacks is an InternalError (a bug)") {
    CHECK_THROWS_AS(k_colours.name(Colour::Unnamed), InternalError);
  }

  TEST_CASE("the core enums go through their tables") {
    CHECK(parse_solver_kind("bicgstab_ilut") == SolverKind::BiCgStabIlut);
    CHECK(to_string(SolverKind::AmgGamg) == "amg_gamg");
    CHECK(solver_names() == k_solver_kind_names.names());
    CHECK(solver_names().size() == 9);
    CHECK_THROWS_WITH_AS(parse_solver_kind("cg"),
                         "unknown linear solver 'cg': use cholmod, umfpack, bicgstab_ilut, "
                         "cg_ic, amg, amg_gamg, pfmg, mumps or superlu_dist",
                         InputError);
    for (IterationMethod m :
         {IterationMethod::Newton, IterationMethod::ModifiedNewton, IterationMethod::Bfgs})
      CHECK(parse_iteration_method(to_string(m)) == m);
    CHECK_THROWS_WITH_AS(parse_iteration_method("lbfgs"),
                         "unknown iteration method 'lbfgs': use newton, modified_newton or bfgs",
                         InputError);
  }
}  // TEST_SUITE
