#include "core/json.h"

#include "core/error.h"
#include "testing/testing.h"

namespace ssiu {
namespace {

using ::testing::HasSubstr;

using testing::ErrorOf;

TEST(StrictJson, NearestKeyCountsATranspositionAsOneEdit) {
  const std::vector<std::string> keys = {"width", "height", "principal_point", "distortion", "focal_length_px"};
  EXPECT_EQ(NearestKey("principal_piont", keys), "principal_point");
  EXPECT_EQ(NearestKey("distortoin", keys), "distortion");
  EXPECT_EQ(NearestKey("widht", keys), "width");
  EXPECT_EQ(NearestKey("temperature", keys), "");  // nothing close: no suggestion
}

TEST(StrictJson, UnknownKeyNamesFileKeyAndSuggestion) {
  const Json j = {{"width", 1}, {"principal_piont", 2}};
  EXPECT_EQ(ErrorOf([&] {
              CheckKeys(j, {"width", "principal_point"}, "cam.json");
            }),
            "cam.json: unknown key 'principal_piont' (did you mean 'principal_point'?)");
  EXPECT_THAT(ErrorOf([&] {
                CheckKeys(Json{{"zzz", 1}}, {"width", "height"}, "c.json");
              }),
              HasSubstr("unknown key 'zzz' (allowed: width, height)"));
  EXPECT_EQ(ErrorOf([&] { CheckKeys(j, {"width", "principal_piont"}, "cam.json"); }), "no error");
  EXPECT_THAT(ErrorOf([&] { CheckKeys(Json::array(), {"width"}, "c.json"); }), HasSubstr("must be a JSON object"));
}

TEST(StrictJson, DuplicateKeysAreRefusedAtAnyDepth) {
  EXPECT_EQ(ErrorOf([] { ParseJsonStrict(R"({"a": 1, "a": 2})", "f.json"); }), "f.json: duplicate key 'a'");
  EXPECT_EQ(ErrorOf([] { ParseJsonStrict(R"({"a": [{"k": 1}, {"k": 2, "k": 3}]})", "f.json"); }),
            "f.json: duplicate key 'k'");
  // The same key in sibling objects, or an object in an array, is fine.
  const Json j = ParseJsonStrict(R"({"a": {"k": 1}, "b": {"k": 2}, "c": [{"k": 3}, {"k": 4}], "k": 5})", "f.json");
  EXPECT_EQ(j["c"][1]["k"], 4);
  EXPECT_THAT(ErrorOf([] { ParseJsonStrict(R"({"a": 1,})", "f.json"); }), HasSubstr("f.json: not valid JSON"));
}

TEST(StrictJson, TypedReadsRefuseWrongTypesAndOutOfRangeIntegers) {
  const Json j = ParseJsonStrict(
      R"({"n": "3", "big": 4294967299, "half": 2.5, "ok": 7, "flag": 1, "s": 5, "arr": [1, 2, "x"], "neg": -1e300})",
      "f.json");
  EXPECT_EQ(ErrorOf([&] { JsonNumber(j, "n", "f.json"); }), "f.json: field 'n' is not a number (it is a string)");
  EXPECT_THAT(ErrorOf([&] { JsonInt(j, "big", 0, 100000, "f.json"); }),
              HasSubstr("field 'big' must be a whole number in [0, 100000]"));
  EXPECT_THAT(ErrorOf([&] { JsonInt(j, "neg", 0, 100000, "f.json"); }), HasSubstr("field 'neg'"));
  EXPECT_THAT(ErrorOf([&] { JsonInt(j, "half", 0, 10, "f.json"); }), HasSubstr("field 'half'"));
  EXPECT_EQ(JsonInt(j, "ok", 0, 10, "f.json"), 7);
  EXPECT_EQ(JsonIntOr(j, "absent", 3, 0, 10, "f.json"), 3);
  EXPECT_THAT(ErrorOf([&] { JsonBoolOr(j, "flag", false, "f.json"); }), HasSubstr("'flag' must be true or false"));
  EXPECT_THAT(ErrorOf([&] { JsonStringOr(j, "s", "", "f.json"); }), HasSubstr("'s' must be a string"));
  EXPECT_THAT(ErrorOf([&] { JsonNumbers(j, "arr", 3, "f.json"); }), HasSubstr("'arr' must hold 3 finite numbers"));
  EXPECT_THAT(ErrorOf([&] { JsonNumbers(j, "arr", 2, "f.json"); }), HasSubstr("'arr' must be an array of 2"));
}

}  // namespace
}  // namespace ssiu
