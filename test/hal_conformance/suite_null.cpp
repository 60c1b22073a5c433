// Null backends: every operation of every contract they stand in for must
// return HAL_E_UNSUPPORTED (with valid arguments), and close must be safe.
#include "conformance.hpp"

TEST_P(NullConformance, Clock)
{
    hal_clock_t *c = h->clock();
    if (c == nullptr) GTEST_SKIP() << "no clock in this backend set";
    uint64_t t = 42;
    EXPECT_EQ(hal_clock_now_us(c, &t), HAL_E_UNSUPPORTED);
    EXPECT_EQ(t, 42u) << "output touched";
    EXPECT_EQ(hal_clock_sleep_until_us(c, 0), HAL_E_UNSUPPORTED);
    EXPECT_EQ(hal_clock_sleep_until_us(c, UINT64_MAX), HAL_E_UNSUPPORTED) << "must not block";
    hal_clock_close(c);
}

TEST_P(NullConformance, Gpio)
{
    hal_gpio_t *g = h->gpio();
    if (g == nullptr) GTEST_SKIP();
    uint32_t n = 0;
    EXPECT_EQ(hal_gpio_line_count(g, &n), HAL_E_UNSUPPORTED);
    hal_gpio_config_t cfg{};
    cfg.dir = HAL_GPIO_DIR_INPUT;
    cfg.edges = HAL_GPIO_EDGE_BOTH;
    EXPECT_EQ(hal_gpio_configure(g, 0, &cfg), HAL_E_UNSUPPORTED);
    bool v;
    EXPECT_EQ(hal_gpio_read(g, 0, &v), HAL_E_UNSUPPORTED);
    EXPECT_EQ(hal_gpio_write(g, 0, true), HAL_E_UNSUPPORTED);
    hal_gpio_event_t ev;
    EXPECT_EQ(hal_gpio_wait_edge(g, 0, &ev, HAL_TIMEOUT_FOREVER), HAL_E_UNSUPPORTED);
    EXPECT_EQ(hal_gpio_release(g, 0), HAL_E_UNSUPPORTED);
    hal_gpio_close(g);
}

TEST_P(NullConformance, Link)
{
    hal_link_t *l = h->link();
    if (l == nullptr) GTEST_SKIP();
    uint16_t id;
    EXPECT_EQ(hal_link_self_id(l, &id), HAL_E_UNSUPPORTED);
    const uint8_t m[4] = {1, 2, 3, 4};
    EXPECT_EQ(hal_link_send(l, 1, m, sizeof m, 0), HAL_E_UNSUPPORTED);
    EXPECT_EQ(hal_link_send(l, HAL_LINK_BROADCAST, m, sizeof m, HAL_TIMEOUT_FOREVER), HAL_E_UNSUPPORTED);
    uint8_t buf[8];
    hal_link_rx_info_t info;
    EXPECT_EQ(hal_link_recv(l, buf, sizeof buf, &info, HAL_TIMEOUT_FOREVER), HAL_E_UNSUPPORTED);
    EXPECT_EQ(info.len, 0u);
    hal_link_close(l);
}

TEST_P(NullConformance, Storage)
{
    hal_storage_t *s = h->storage();
    if (s == nullptr) GTEST_SKIP();
    const uint8_t m[2] = {1, 2};
    EXPECT_EQ(hal_storage_write(s, "map", m, sizeof m), HAL_E_UNSUPPORTED);
    uint8_t buf[4];
    size_t len = 7;
    EXPECT_EQ(hal_storage_read(s, "map", buf, sizeof buf, &len), HAL_E_UNSUPPORTED);
    EXPECT_EQ(len, 0u);
    EXPECT_EQ(hal_storage_remove(s, "map"), HAL_E_UNSUPPORTED);
    bool e = true;
    EXPECT_EQ(hal_storage_exists(s, "map", &e), HAL_E_UNSUPPORTED);
    EXPECT_FALSE(e);
    hal_storage_close(s);
}

TEST_P(NullConformance, Camera)
{
    hal_camera_t *c = h->camera();
    if (c == nullptr) GTEST_SKIP();
    hal_camera_format_t f;
    EXPECT_EQ(hal_camera_get_format(c, &f), HAL_E_UNSUPPORTED);
    EXPECT_EQ(hal_camera_start(c), HAL_E_UNSUPPORTED);
    EXPECT_EQ(hal_camera_stop(c), HAL_E_UNSUPPORTED);
    uint8_t buf[16];
    hal_camera_frame_info_t info;
    EXPECT_EQ(hal_camera_grab(c, buf, sizeof buf, &info, HAL_TIMEOUT_FOREVER), HAL_E_UNSUPPORTED);
    EXPECT_EQ(info.len, 0u);
    hal_camera_close(c);
}

TEST_P(NullConformance, Serial)
{
    hal_serial_t *s = h->serial();
    if (s == nullptr) GTEST_SKIP();
    EXPECT_EQ(hal_serial_set_baud(s, 115200), HAL_E_UNSUPPORTED);
    const uint8_t m[2] = {1, 2};
    EXPECT_EQ(hal_serial_write(s, m, sizeof m, 0), HAL_E_UNSUPPORTED);
    uint8_t buf[4];
    size_t n = 5;
    EXPECT_EQ(hal_serial_read(s, buf, sizeof buf, &n, HAL_TIMEOUT_FOREVER), HAL_E_UNSUPPORTED);
    EXPECT_EQ(n, 0u);
    EXPECT_EQ(hal_serial_flush_input(s), HAL_E_UNSUPPORTED);
    hal_serial_close(s);
}
