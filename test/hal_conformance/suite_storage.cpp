// hal_storage contract conformance (see hal/hal_storage.h).
#include <cstring>
#include <string>

#include "conformance.hpp"

using conf::pattern;

namespace {

hal_status_t put(hal_storage_t *s, const char *name, const std::vector<uint8_t> &v)
{
    return hal_storage_write(s, name, v.data(), v.size());
}

std::vector<uint8_t> get(hal_storage_t *s, const char *name, hal_status_t *st)
{
    std::vector<uint8_t> buf(1 << 20);
    size_t len = 0;
    *st = hal_storage_read(s, name, buf.data(), buf.size(), &len);
    buf.resize(*st == HAL_OK ? len : 0);
    return buf;
}

bool exists(hal_storage_t *s, const char *name)
{
    bool e = true;
    EXPECT_EQ(hal_storage_exists(s, name, &e), HAL_OK);
    return e;
}

}  // namespace

TEST_P(StorageConformance, WriteReadRoundTrip)
{
    const auto v = pattern(1000, 1);
    ASSERT_EQ(put(h->dev(), "map", v), HAL_OK);
    hal_status_t st;
    EXPECT_EQ(get(h->dev(), "map", &st), v);
    EXPECT_EQ(st, HAL_OK);
}

TEST_P(StorageConformance, WriteReplacesWhole)
{
    ASSERT_EQ(put(h->dev(), "cfg", pattern(5000, 2)), HAL_OK);
    const auto small = pattern(7, 3);
    ASSERT_EQ(put(h->dev(), "cfg", small), HAL_OK);
    hal_status_t st;
    EXPECT_EQ(get(h->dev(), "cfg", &st), small) << "shrinking replace must not keep a tail";
    const auto big = pattern(70000, 4);
    ASSERT_EQ(put(h->dev(), "cfg", big), HAL_OK);
    EXPECT_EQ(get(h->dev(), "cfg", &st), big);
}

TEST_P(StorageConformance, ExistsAndRemove)
{
    EXPECT_FALSE(exists(h->dev(), "calib"));
    ASSERT_EQ(put(h->dev(), "calib", pattern(10, 5)), HAL_OK);
    EXPECT_TRUE(exists(h->dev(), "calib"));
    EXPECT_EQ(hal_storage_remove(h->dev(), "calib"), HAL_OK);
    EXPECT_FALSE(exists(h->dev(), "calib"));
    hal_status_t st;
    get(h->dev(), "calib", &st);
    EXPECT_EQ(st, HAL_E_NOT_FOUND);
}

TEST_P(StorageConformance, MissingIsNotFound)
{
    uint8_t buf[4];
    size_t len = 99;
    EXPECT_EQ(hal_storage_read(h->dev(), "nothing", buf, sizeof buf, &len), HAL_E_NOT_FOUND);
    EXPECT_EQ(len, 0u);
    EXPECT_EQ(hal_storage_remove(h->dev(), "nothing"), HAL_E_NOT_FOUND);
}

TEST_P(StorageConformance, SmallBufferReportsNeededSize)
{
    const auto v = pattern(300, 6);
    ASSERT_EQ(put(h->dev(), "blob", v), HAL_OK);
    std::vector<uint8_t> buf(299);
    size_t len = 0;
    EXPECT_EQ(hal_storage_read(h->dev(), "blob", buf.data(), buf.size(), &len), HAL_E_OVERFLOW);
    EXPECT_EQ(len, 300u);
    len = 0;
    EXPECT_EQ(hal_storage_read(h->dev(), "blob", nullptr, 0, &len), HAL_E_OVERFLOW) << "size query";
    EXPECT_EQ(len, 300u);
    // the retry with the reported size succeeds, and the blob is unharmed
    buf.resize(len);
    ASSERT_EQ(hal_storage_read(h->dev(), "blob", buf.data(), buf.size(), &len), HAL_OK);
    EXPECT_EQ(buf, v);
}

TEST_P(StorageConformance, ZeroLengthBlob)
{
    ASSERT_EQ(hal_storage_write(h->dev(), "empty", nullptr, 0), HAL_OK);
    EXPECT_TRUE(exists(h->dev(), "empty"));
    size_t len = 99;
    EXPECT_EQ(hal_storage_read(h->dev(), "empty", nullptr, 0, &len), HAL_OK);
    EXPECT_EQ(len, 0u);
}

TEST_P(StorageConformance, NamesAreIndependentAndCaseSensitive)
{
    const auto a = pattern(64, 7), b = pattern(65, 8), c = pattern(66, 9);
    ASSERT_EQ(put(h->dev(), "map", a), HAL_OK);
    ASSERT_EQ(put(h->dev(), "Map", b), HAL_OK);
    ASSERT_EQ(put(h->dev(), "map.bak", c), HAL_OK);
    hal_status_t st;
    EXPECT_EQ(get(h->dev(), "map", &st), a);
    EXPECT_EQ(get(h->dev(), "Map", &st), b);
    EXPECT_EQ(get(h->dev(), "map.bak", &st), c);
    ASSERT_EQ(hal_storage_remove(h->dev(), "Map"), HAL_OK);
    EXPECT_EQ(get(h->dev(), "map", &st), a);
}

TEST_P(StorageConformance, NameRulesEnforced)
{
    const uint8_t x = 1;
    const std::string longest(HAL_STORAGE_NAME_MAX, 'a');
    const std::string too_long(HAL_STORAGE_NAME_MAX + 1, 'a');
    EXPECT_EQ(hal_storage_write(h->dev(), longest.c_str(), &x, 1), HAL_OK);
    EXPECT_EQ(hal_storage_write(h->dev(), "A-z_0.9", &x, 1), HAL_OK);
    for (const char *bad : {"", ".hidden", "a/b", "..", "sp ace", "semi;colon", "uml\xc3\xa4ut"}) {
        EXPECT_EQ(hal_storage_write(h->dev(), bad, &x, 1), HAL_E_ARG) << bad;
        bool e = true;
        EXPECT_EQ(hal_storage_exists(h->dev(), bad, &e), HAL_E_ARG) << bad;
        EXPECT_EQ(hal_storage_remove(h->dev(), bad), HAL_E_ARG) << bad;
    }
    EXPECT_EQ(hal_storage_write(h->dev(), too_long.c_str(), &x, 1), HAL_E_ARG);
    EXPECT_EQ(hal_storage_write(h->dev(), nullptr, &x, 1), HAL_E_ARG);
    EXPECT_EQ(hal_storage_write(h->dev(), "ok", nullptr, 1), HAL_E_ARG);
    size_t len;
    EXPECT_EQ(hal_storage_read(h->dev(), "ok", nullptr, 4, &len), HAL_E_ARG);
    uint8_t b;
    EXPECT_EQ(hal_storage_read(h->dev(), "ok", &b, 1, nullptr), HAL_E_ARG);
}

TEST_P(StorageConformance, EveryByteValueSurvives)
{
    std::vector<uint8_t> v(256 * 4);
    for (size_t i = 0; i < v.size(); ++i) v[i] = static_cast<uint8_t>(i);
    ASSERT_EQ(put(h->dev(), "bytes", v), HAL_OK);
    hal_status_t st;
    EXPECT_EQ(get(h->dev(), "bytes", &st), v);
}

TEST_P(StorageConformance, PersistsAcrossReopen)
{
    const auto v = pattern(4096, 10);
    ASSERT_EQ(put(h->dev(), "persist", v), HAL_OK);
    ASSERT_EQ(put(h->dev(), "gone", v), HAL_OK);
    ASSERT_EQ(hal_storage_remove(h->dev(), "gone"), HAL_OK);
    hal_storage_t *s = h->reopen();
    ASSERT_NE(s, nullptr);
    hal_status_t st;
    EXPECT_EQ(get(s, "persist", &st), v);
    EXPECT_FALSE(exists(s, "gone"));
}
