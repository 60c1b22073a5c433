#include "coslam/pose2.h"

#include <math.h>

double angle_wrap(double angle_rad)
{
    if (!isfinite(angle_rad)) {
        return NAN;
    }
    if (angle_rad >= -COSLAM_PI && angle_rad < COSLAM_PI) {
        return angle_rad; /* the common case, exact */
    }
    double w = fmod(angle_rad + COSLAM_PI, COSLAM_TWO_PI);
    if (w < 0.0) {
        w += COSLAM_TWO_PI;
    }
    w -= COSLAM_PI;
    /* fmod is exact but the shifts may round onto +pi */
    if (w >= COSLAM_PI) {
        w -= COSLAM_TWO_PI;
    }
    return w;
}

pose2_t pose2_compose(pose2_t a, pose2_t b)
{
    const double c = cos(a.theta);
    const double s = sin(a.theta);
    pose2_t r;
    r.x = a.x + c * b.x - s * b.y;
    r.y = a.y + s * b.x + c * b.y;
    r.theta = angle_wrap(a.theta + b.theta);
    return r;
}

pose2_t pose2_inverse(pose2_t a)
{
    const double c = cos(a.theta);
    const double s = sin(a.theta);
    pose2_t r;
    r.x = -c * a.x - s * a.y;
    r.y = s * a.x - c * a.y;
    r.theta = angle_wrap(-a.theta);
    return r;
}

pose2_t pose2_between(pose2_t a, pose2_t b)
{
    return pose2_compose(pose2_inverse(a), b);
}

point2_t pose2_apply_cs(pose2_t a, double c, double s, point2_t p)
{
    point2_t r;
    r.x = a.x + c * p.x - s * p.y;
    r.y = a.y + s * p.x + c * p.y;
    return r;
}

point2_t pose2_apply(pose2_t a, point2_t p)
{
    return pose2_apply_cs(a, cos(a.theta), sin(a.theta), p);
}

point2_t pose2_apply_inverse_cs(pose2_t a, double c, double s, point2_t p)
{
    const double dx = p.x - a.x;
    const double dy = p.y - a.y;
    point2_t r;
    r.x = c * dx + s * dy;
    r.y = -s * dx + c * dy;
    return r;
}

point2_t pose2_apply_inverse(pose2_t a, point2_t p)
{
    return pose2_apply_inverse_cs(a, cos(a.theta), sin(a.theta), p);
}

void pose2_compose_jacobians(pose2_t a, pose2_t b, double ja[3][3], double jb[3][3])
{
    const double c = cos(a.theta);
    const double s = sin(a.theta);
    if (ja != 0) {
        ja[0][0] = 1.0; ja[0][1] = 0.0; ja[0][2] = -s * b.x - c * b.y;
        ja[1][0] = 0.0; ja[1][1] = 1.0; ja[1][2] = c * b.x - s * b.y;
        ja[2][0] = 0.0; ja[2][1] = 0.0; ja[2][2] = 1.0;
    }
    if (jb != 0) {
        jb[0][0] = c;   jb[0][1] = -s;  jb[0][2] = 0.0;
        jb[1][0] = s;   jb[1][1] = c;   jb[1][2] = 0.0;
        jb[2][0] = 0.0; jb[2][1] = 0.0; jb[2][2] = 1.0;
    }
}

void pose2_apply_jacobians(pose2_t a, point2_t p, double j_pose[2][3], double j_point[2][2])
{
    const double c = cos(a.theta);
    const double s = sin(a.theta);
    if (j_pose != 0) {
        j_pose[0][0] = 1.0; j_pose[0][1] = 0.0; j_pose[0][2] = -s * p.x - c * p.y;
        j_pose[1][0] = 0.0; j_pose[1][1] = 1.0; j_pose[1][2] = c * p.x - s * p.y;
    }
    if (j_point != 0) {
        j_point[0][0] = c; j_point[0][1] = -s;
        j_point[1][0] = s; j_point[1][1] = c;
    }
}

int pose2_is_finite(pose2_t a)
{
    return isfinite(a.x) && isfinite(a.y) && isfinite(a.theta);
}
