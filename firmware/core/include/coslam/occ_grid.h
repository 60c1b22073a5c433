/*
 * coslam/occ_grid.h - fixed-size log-odds occupancy grid fed by laser scans.
 *
 * The grid is COSLAM_GRID_CELLS_X x COSLAM_GRID_CELLS_Y square cells of
 * COSLAM_GRID_CELL_MM (config.h), axis-aligned with the map frame. Cell
 * (ix, iy) covers [ox + ix c, ox + (ix+1) c) x [oy + iy c, oy + (iy+1) c),
 * with (ox, oy) the map-frame corner given at init and c the cell edge [m].
 *
 * Each cell holds the log-odds l = ln(p / (1 - p)) of being occupied, 0 for
 * unknown (p = 0.5), stored as int16_t in units of 1/OCC_GRID_LOGODDS_SCALE.
 * A scan updates it with the standard inverse sensor model (Thrun, Burgard,
 * Fox, "Probabilistic Robotics", table 9.1 / 9.2): every cell a ray crosses
 * before its end gets l += l_free (< 0), the end cell of a return gets
 * l += l_occ (> 0); the result is clamped to [l_min, l_max] so the map stays
 * able to change its mind.
 *
 * Rays are traced cell by cell with Bresenham's line algorithm between the
 * sensor's cell and the end point's cell (integer arithmetic, every cell on
 * the 8-connected digital line, one per step of the major axis).
 *
 * Ranges (per ray, in the sensor frame, from urg_scip2_scan_polar()):
 *  - NaN, negative, or below min_range_m: invalid, skipped, counted.
 *  - finite and <= max_range_m: a return; free cells up to it, end occupied.
 *  - +INFINITY or > max_range_m: no return; free cells up to
 *    no_return_free_m only (0 disables), nothing occupied.
 * A return whose end point lies outside the grid is counted (out_of_grid)
 * and makes the call return COSLAM_E_CAPACITY; the part of its ray inside
 * the grid is still marked free. Rays are clipped at the grid border.
 *
 * Memory: sizeof(occ_grid_t) = 2 * CELLS_X * CELLS_Y + ~150 bytes (80 KB for
 * the default 200 x 200). No heap, no globals; the caller owns the grid.
 */
#ifndef COSLAM_OCC_GRID_H
#define COSLAM_OCC_GRID_H

#include <stddef.h>
#include <stdint.h>

#include "coslam/config.h"
#include "coslam/pose2.h"
#include "coslam/status.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Stored log-odds units per nat. */
#define OCC_GRID_LOGODDS_SCALE 1000.0
/** Longest ray a grid accepts as max_range_m / no_return_free_m [m]: bounds
 *  the work per ray (and keeps cell indices far from overflow). */
#define OCC_GRID_MAX_RAY_M 1000.0
/** Edge of a cell [m]. */
#define OCC_GRID_CELL_M ((double)COSLAM_GRID_CELL_MM / 1000.0)

typedef struct {
    double l_occ;            /**< log-odds added to a return's end cell (> 0) */
    double l_free;           /**< log-odds added to each crossed cell (< 0) */
    double l_min;            /**< lower clamp (< 0) */
    double l_max;            /**< upper clamp (> 0) */
    double min_range_m;      /**< shorter readings are invalid [m] (>= 0) */
    double max_range_m;      /**< longer readings are no-returns [m] (> min_range_m) */
    double no_return_free_m; /**< free length marked along a no-return ray [m] (>= 0) */
} occ_grid_params_t;

typedef struct {
    uint32_t scans;        /**< scans integrated (calls that got past the argument checks) */
    uint32_t hits;         /**< returns whose end cell was marked occupied */
    uint32_t no_returns;   /**< no-return rays (free up to no_return_free_m) */
    uint32_t invalid;      /**< rays skipped: NaN, negative or below min range */
    uint32_t out_of_grid;  /**< returns whose end point fell outside the grid */
    uint32_t saturated;    /**< cell updates that hit l_min or l_max */
} occ_grid_stats_t;

typedef struct {
    int16_t cell[COSLAM_GRID_CELLS_Y][COSLAM_GRID_CELLS_X]; /**< log-odds, [iy][ix] */
    double origin_x_m;  /**< map x of the outer corner of cell (0, 0) [m] */
    double origin_y_m;  /**< map y of the outer corner of cell (0, 0) [m] */
    occ_grid_params_t params;
    int16_t q_occ, q_free, q_min, q_max; /**< params in stored units */
    occ_grid_stats_t stats;
} occ_grid_t;

/** Per-call outcome of occ_grid_integrate_scan (counts for this scan only). */
typedef struct {
    uint32_t hits;
    uint32_t no_returns;
    uint32_t invalid;
    uint32_t out_of_grid;
    uint32_t cells_updated;
} occ_grid_result_t;

/** Defaults: l_occ = ln(0.7/0.3) = 0.847, l_free = ln(0.4/0.6) = -0.405,
 *  clamp [-2, 3.5], ranges [0.02, 5.6] m (URG-04LX), no-return free 2 m. */
void occ_grid_params_default(occ_grid_params_t *p);

/**
 * Initialise every cell to unknown (0). p NULL means defaults. Returns
 * COSLAM_OK; COSLAM_E_ARG for a NULL grid, non-finite values, l_occ <= 0,
 * l_free >= 0, l_min >= 0, l_max <= 0, clamps beyond the int16 range,
 * min_range_m < 0, max_range_m <= min_range_m, no_return_free_m < 0,
 * max_range_m or no_return_free_m above OCC_GRID_MAX_RAY_M.
 * O(cells).
 */
coslam_status_t occ_grid_init(occ_grid_t *g, const occ_grid_params_t *p, double origin_x_m, double origin_y_m);

/** All cells back to unknown; counters to zero. O(cells). */
void occ_grid_clear(occ_grid_t *g);

/**
 * Integrate one scan. sensor_pose is the laser's pose in the map frame;
 * ray i has range range_m[i] [m] at angle_rad[i] [rad] in the sensor frame
 * (counter-clockwise from the sensor's x axis). res may be NULL.
 * Returns COSLAM_OK; COSLAM_E_ARG (NULL grid, NULL arrays with n > 0, or a
 * sensor farther than 1e6 cells from the grid: nothing integrated);
 * COSLAM_E_NUMERIC (non-finite pose: nothing integrated); COSLAM_E_CAPACITY
 * if at least one return ended outside the grid (everything else was
 * integrated; stats.out_of_grid counts them). Invalid ranges and non-finite
 * angles are skipped and counted, not errors.
 * Complexity O(sum of ray lengths in cells), no memory beyond the stack.
 */
coslam_status_t occ_grid_integrate_scan(occ_grid_t *g, pose2_t sensor_pose, const double *range_m,
                                        const double *angle_rad, size_t n, occ_grid_result_t *res);

/** Cell holding map point (x, y): 1 and *ix, *iy if inside the grid, else 0. */
int occ_grid_cell_of(const occ_grid_t *g, double x_m, double y_m, int32_t *ix, int32_t *iy);

/** Map-frame centre of cell (ix, iy) (any indices, inside or not). */
point2_t occ_grid_cell_center(const occ_grid_t *g, int32_t ix, int32_t iy);

/** Log-odds of a cell [nat]; 0 (unknown) outside the grid. */
double occ_grid_logodds(const occ_grid_t *g, int32_t ix, int32_t iy);

/** Occupancy probability of a cell, 1 - 1 / (1 + exp(l)); 0.5 outside. */
double occ_grid_prob(const occ_grid_t *g, int32_t ix, int32_t iy);

/** Counters of this grid. */
const occ_grid_stats_t *occ_grid_stats(const occ_grid_t *g);

/**
 * 1 if the segment a -> b (map frame) crosses no cell with log-odds above
 * l_occupied, ignoring the last skip_end_m before b (the target itself, a
 * post the laser sees); cells outside the grid count as free. Sampled every
 * half cell. O(|ab| / cell), no memory.
 */
int occ_grid_line_free(const occ_grid_t *g, point2_t a, point2_t b, double l_occupied, double skip_end_m);

#ifdef __cplusplus
}
#endif

#endif /* COSLAM_OCC_GRID_H */
