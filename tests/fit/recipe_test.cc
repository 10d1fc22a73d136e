#include "stagefit/fit/recipe.h"

#include <gtest/gtest.h>

#include <filesystem>

#include "stagefit/common/error.h"

namespace stagefit::fit {
namespace {

std::string ErrorOf(const std::string& text) {
  try {
    ParseFitRecipe(text, "r.toml");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(ParseFitRecipe, ReadsEveryKey) {
  const FitRecipe r = ParseFitRecipe(R"(
measurement = "m.mat"
space = "raw"
band = ["5 Hz", 700]
significance = 0.2
params = ["hexapod.k.*", "rz.k.Dz"]
solver = "nlopt"
jacobian = "finite-difference"
nlopt_algorithm = "GN_DIRECT"
nlopt_max_evaluations = 500
polish = false
starts = 8
start_factor = 2.5
seed = 42
max_iterations = 30
probe_rounds = 2
[[bounds]]
pattern = "hexapod.k.R?"
lower = "0.2 Nm/urad"
upper = 1e7
[[bounds]]
pattern = "rz.k.Dz"
factor = 5
)",
                                     "r.toml", "/data/recipes");
  EXPECT_EQ(r.measurement, "/data/recipes/m.mat");
  EXPECT_EQ(r.comparison.space, compare::ComparisonSpace::kRaw);
  EXPECT_DOUBLE_EQ(r.comparison.fmin_hz, 5.0);
  EXPECT_DOUBLE_EQ(r.comparison.fmax_hz, 700.0);
  EXPECT_DOUBLE_EQ(r.comparison.significance_threshold, 0.2);
  EXPECT_EQ(r.params, (std::vector<std::string>{"hexapod.k.*", "rz.k.Dz"}));
  EXPECT_EQ(r.options.solver, SolverKind::kNlopt);
  EXPECT_EQ(r.options.jacobian, JacobianKind::kFiniteDifference);
  EXPECT_EQ(r.options.nlopt_algorithm, "GN_DIRECT");
  EXPECT_EQ(r.options.nlopt_max_evaluations, 500);
  EXPECT_FALSE(r.options.nlopt_polish);
  EXPECT_EQ(r.options.num_starts, 8);
  EXPECT_DOUBLE_EQ(r.options.start_factor, 2.5);
  EXPECT_EQ(r.options.seed, 42u);
  EXPECT_EQ(r.options.max_iterations, 30);
  EXPECT_EQ(r.options.max_probe_rounds, 2);
  ASSERT_EQ(r.bounds.size(), 2u);
  EXPECT_DOUBLE_EQ(*r.bounds[0].lower, 2e5);
  EXPECT_DOUBLE_EQ(*r.bounds[0].upper, 1e7);
  EXPECT_TRUE(r.bounds[0].dimension == dim::kRotationalStiffness);
  EXPECT_EQ(r.bounds[0].source, "r.toml:17");  // the [[bounds]] header line
  EXPECT_DOUBLE_EQ(*r.bounds[1].factor, 5.0);
}

TEST(ParseFitRecipe, EmptyRecipeKeepsTheDefaults) {
  const FitRecipe r = ParseFitRecipe("", "r.toml");
  EXPECT_TRUE(r.measurement.empty());
  EXPECT_TRUE(r.params.empty());
  EXPECT_EQ(r.options.solver, SolverKind::kCeres);
  EXPECT_EQ(r.options.num_starts, 1);
}

TEST(ParseFitRecipe, ErrorsNameFileLineKeyValueAndExpectation) {
  EXPECT_NE(ErrorOf("solvr = \"ceres\"").find("r.toml:1: solvr is an unknown key"), std::string::npos);
  EXPECT_NE(ErrorOf("\nsolver = \"lbfgs\"").find("r.toml:2: solver = 'lbfgs', expected ceres or nlopt"),
            std::string::npos);
  EXPECT_NE(ErrorOf("starts = 0").find("starts = 0, expected an integer >= 1"), std::string::npos);
  EXPECT_NE(ErrorOf("band = [700, 5]").find("expected 0 <= low < high"), std::string::npos);
  EXPECT_NE(ErrorOf("band = [\"5 N\", 700]").find("band[0]"), std::string::npos);
  EXPECT_NE(ErrorOf("nlopt_algorithm = \"FAST\"").find("nlopt_algorithm"), std::string::npos);
  EXPECT_NE(ErrorOf("[[bounds]]\npattern = \"a\"\nfactor = 0.5").find("r.toml:3: bounds[0].factor = 0.5"),
            std::string::npos);
  EXPECT_NE(ErrorOf("[[bounds]]\nlower = 1").find("bounds[0].pattern is missing"), std::string::npos);
  EXPECT_NE(ErrorOf("params = \"*.k.*\"").find("expected a non-empty array"), std::string::npos);
  EXPECT_NE(ErrorOf("seed = = 1").find("TOML syntax error"), std::string::npos);
  // Every problem is reported at once.
  EXPECT_NE(ErrorOf("starts = 0\nseed = -1").find("2 problems"), std::string::npos);
}

TEST(ReadFitRecipe, TheShippedRecipesParse) {
  for (const char* name : {"recipe-stiffness.toml", "recipe-global.toml"}) {
    EXPECT_NO_THROW(ReadFitRecipe(std::filesystem::path(STAGEFIT_SOURCE_DIR) / "fitting" / name)) << name;
  }
  EXPECT_THROW(ReadFitRecipe("/nonexistent/recipe.toml"), InputError);
}

}  // namespace
}  // namespace stagefit::fit
