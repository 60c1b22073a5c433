/* Force-included (-include) into the reference Fast-SLAM and its driver:
 * its public symbols get a ref_ prefix, so it links beside the core's. */
#define fastslam_config_default ref_fastslam_config_default
#define fastslam_init ref_fastslam_init
#define fastslam_predict ref_fastslam_predict
#define fastslam_update ref_fastslam_update
#define fastslam_pose_estimate ref_fastslam_pose_estimate
#define fastslam_export ref_fastslam_export
#define fastslam_best_particle ref_fastslam_best_particle
#define fastslam_reweighted ref_fastslam_reweighted
#define fastslam_weights ref_fastslam_weights
#define fastslam_resample ref_fastslam_resample
#define fastslam_particle_add ref_fastslam_particle_add
#define fastslam_new_id ref_fastslam_new_id
