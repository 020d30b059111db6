//! The site model written for every LIAS run.

use super::calibration::Calibration;
use super::{ANCHORS, RIGID_BODY_HEIGHT_M};

/// `site.toml` of a LIAS run: the eight anchors with their post-calibration range std, and the
/// tracker settings, every choice explained in a comment.
pub(super) fn site_toml(calibration: &Calibration) -> String {
    let mut text = String::from(
        "# LIAS CUHK-SZ planar rigid-body UWB dataset (Jiang et al., ICRA 2023), written by `rtls import`.\n\
         # Frame: the motion-capture frame, m. Tags T0, T1, T2 sit on one rigid body (trolley); anchors A0..A7.\n\
         name = \"LIAS CUHK-SZ planar RBL: 8 UWB TWR anchors, 3 tags on a trolley\"\n\n\
         # Anchor coordinates from the dataset README. range_std_m = the post-calibration residual std of this\n\
         # anchor's ranges on the 5 static runs (3 tags pooled; includes the pose-to-pose variation of the bias).\n\
         # bias_m = 0: measurements.jsonl already has the per-(anchor, tag) bias removed (../calibration.csv);\n\
         # measurements-raw.jsonl keeps the recorded ranges (median +0.17 m against the truth).\n",
    );
    for (anchor, (id, position)) in ANCHORS.iter().enumerate() {
        let std_m = calibration.anchor_std_m[anchor];
        text.push_str(&format!(
            "[[readers]]\nid = \"{id}\"\nposition_m = [{:?}, {:?}, {:?}]\ntechnology = \"uwb\"\n\
             radio = {{ range = {{ range_std_m = {:.4}, bias_m = 0.0 }} }}\n\n",
            position[0], position[1], position[2], std_m
        ));
    }
    text.push_str(&format!(
        "[tracker]\n\
         # Raw ranges update the filter directly.\n\
         pipeline = \"tightly-coupled\"\n\
         motion_model = \"cv\"\n\
         filter = \"ekf\"\n\
         # A hand-pushed trolley: mean speed 0.24-0.48 m/s, speed and heading change over about a second,\n\
         # i.e. accelerations of a few tenths of m/s^2; 0.5 m/s^2 white acceleration covers the turns.\n\
         acceleration_noise_std_mps2 = 0.5\n\
         gate_probability = 0.999\n\
         initiation = {{ confirm_updates = 3, within_s = 2.0 }}\n\
         coast_timeout_s = 2.0\n\
         delete_timeout_s = 60.0\n\
         # The UWB log is written in time order; 0.1 s covers logger jitter (rows arrive 1-28 ms apart).\n\
         reorder_window_s = 0.1\n\
         # Planar problem: anchors at 1.04 m and tags at 0.97 m (3-D is ill-conditioned in z).\n\
         dimensions = 2\n\
         # One ranging round = one row of the UWB log: all 8 ranges of a tag share one time stamp, and rows\n\
         # are 10 ms apart on average but only 1 ms apart at times (logger jitter). A window of 0 groups\n\
         # exactly equal time stamps, i.e. exactly one round; any window > 0 would sometimes merge two.\n\
         epoch_s = 0.0\n\
         # Height of the tags (rigid-body centroid from the motion capture, 0.95-0.99 m): slant ranges to the\n\
         # anchors at 1.04 m are projected to the plane with it.\n\
         tag_height_m = {RIGID_BODY_HEIGHT_M:?}\n"
    ));
    text
}
