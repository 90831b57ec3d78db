#include <gtest/gtest.h>

#include "nmbake/common.hpp"

TEST(Status, CarriesCodeAndMessage) {
  const nmbake::Status s = nmbake::Status::bad_input("low.obj:3: bad index");
  EXPECT_FALSE(s.is_ok());
  EXPECT_EQ(s.code(), nmbake::StatusCode::bad_input);
  EXPECT_EQ(s.message(), "low.obj:3: bad index");
  EXPECT_TRUE(nmbake::Status::ok().is_ok());
}
