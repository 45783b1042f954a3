// Block parameters by name: parse_free_params, default_free_params, param_value / set_param against the fields of
// BlockParams they stand for.
#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "model/fit/band_fit.hpp"

namespace noisemon::model {
namespace {

TEST(BandFitParams, EveryNameRoundTripsAndReadsAndWritesItsOwnField) {
  BlockParams q;
  q.k1 = 1.0;
  q.b1 = 2.0;
  q.k3 = 3.0;
  q.b3 = 4.0;
  q.c0 = 5.0;
  q.c1 = 6.0;
  const std::vector<fit::BlockParam> all = fit::parse_free_params("k1,b1,k3,b3,c0,c1");
  ASSERT_EQ(all.size(), 6u);
  const double expected[] = {1.0, 2.0, 3.0, 4.0, 5.0, 6.0};
  for (std::size_t i = 0; i < all.size(); ++i) {
    EXPECT_EQ(fit::parse_free_params(fit::param_name(all[i])), std::vector<fit::BlockParam>{all[i]});
    EXPECT_EQ(fit::param_value(q, all[i]), expected[i]) << fit::param_name(all[i]);
    BlockParams w = q;
    fit::set_param(w, all[i], -1.0);
    EXPECT_EQ(fit::param_value(w, all[i]), -1.0);
    for (fit::BlockParam other : all) {
      if (other != all[i]) {
        EXPECT_EQ(param_value(w, other), param_value(q, other));
      }
    }
    EXPECT_EQ(w.m, q.m);
  }
}

TEST(BandFitParams, ParsingTrimsSpacesDropsRepeatsAndKeepsTheOrderGiven) {
  EXPECT_EQ(fit::parse_free_params(" c0 , k1,c0,,b1 "),
            (std::vector<fit::BlockParam>{fit::BlockParam::kC0, fit::BlockParam::kK1, fit::BlockParam::kB1}));
}

TEST(BandFitParams, UnknownOrMissingNamesAreErrorsNamingThem) {
  try {
    fit::parse_free_params("k1,m");
    FAIL() << "m is fixed";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'m'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(fit::parse_free_params(""), std::invalid_argument);
  EXPECT_THROW(fit::parse_free_params(" , "), std::invalid_argument);
}

TEST(BandFitParams, DefaultFreeSetAddsTheCubicTermsTheStartHas) {
  BlockParams linear;
  const std::vector<fit::BlockParam> base{fit::BlockParam::kK1, fit::BlockParam::kB1, fit::BlockParam::kC0,
                                          fit::BlockParam::kC1};
  EXPECT_EQ(fit::default_free_params(linear), base);
  BlockParams cubic = linear;
  cubic.k3 = 1e12;
  cubic.b3 = 100.0;
  std::vector<fit::BlockParam> both = base;
  both.push_back(fit::BlockParam::kK3);
  both.push_back(fit::BlockParam::kB3);
  EXPECT_EQ(fit::default_free_params(cubic), both);
}

}  // namespace
}  // namespace noisemon::model
