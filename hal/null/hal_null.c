/*
 * hal_null.c - the null backends: one static instance per contract whose
 * ops table is all NULL, so every wrapper returns HAL_E_UNSUPPORTED. They
 * stand in for missing hardware (a robot without a camera) and for
 * backends not written yet (Linux camera and link). Stateless, so one
 * shared instance per contract is enough.
 */
#include "hal/hal_camera.h"
#include "hal/hal_clock.h"
#include "hal/hal_gpio.h"
#include "hal/hal_link.h"
#include "hal/hal_storage.h"

static const hal_clock_ops_t clock_null_ops = {0};
static const hal_gpio_ops_t gpio_null_ops = {0};
static const hal_link_ops_t link_null_ops = {0};
static const hal_storage_ops_t storage_null_ops = {0};
static const hal_camera_ops_t camera_null_ops = {0};

static hal_clock_t clock_null = {&clock_null_ops, NULL};
static hal_gpio_t gpio_null = {&gpio_null_ops, NULL};
static hal_link_t link_null = {&link_null_ops, NULL};
static hal_storage_t storage_null = {&storage_null_ops, NULL};
static hal_camera_t camera_null = {&camera_null_ops, NULL};

hal_clock_t *hal_clock_null(void) { return &clock_null; }
hal_gpio_t *hal_gpio_null(void) { return &gpio_null; }
hal_link_t *hal_link_null(void) { return &link_null; }
hal_storage_t *hal_storage_null(void) { return &storage_null; }
hal_camera_t *hal_camera_null(void) { return &camera_null; }
