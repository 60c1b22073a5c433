# What the default profile may take on a Cortex-M7 (bytes), checked by the
# core_cortexm_footprint test (cmake/check_footprint.cmake) in every CTest
# run. Measured 2026-12-07: Fast-SLAM image static RAM 743,720, EKF-SLAM
# image 249,336, sizeof(robot_node_t) 911,288 (README "The SLAM core in
# numbers", docs/robot-app.md "Memory and code size").
#
# The Fast-SLAM image's budget is issue 13's bound, not a margin: the
# default profile may grow by at most 10 % for the scale work, and the
# image before the landmark tree (docs/core-slam.md) held 676,464 B of .bss
# and 112 B of .data, so 676,576 x 1.10 = 744,233 B. It is 513 B under
# that now. A change that needs more makes room first; raising this
# budget breaks issue 13's goal and must say so.
#
# The other two budgets are about 2 % above their figures: a change that
# needs more raises the budget here, in the same commit, and says why.
set(COSLAM_BUDGET_FASTSLAM_STATIC_RAM 744233)
set(COSLAM_BUDGET_EKFSLAM_STATIC_RAM 255000)
set(COSLAM_BUDGET_ROBOT_NODE 929500)
