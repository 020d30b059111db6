//! L-WKNN against global WKNN on a seed-002-style grid site of UJIIndoorLoc's size with known
//! anchor positions (520 anchors, 19 964 reference points): seed 002's claim that L-WKNN finds
//! the same neighbours, at a fraction of the comparisons. The query time of the same
//! configurations is benchmarked in `benches/fingerprint.rs`.

use rand::{Rng, SeedableRng};
use rtls_positioning::fingerprint::{FingerprintDatabase, FingerprintIndex, LocalWknn};
use rtls_sim::GridSite;

#[test]
fn l_wknn_finds_the_global_neighbours_at_ujiindoorloc_size() {
    let site = GridSite::ujiindoorloc_size();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2002);
    let database = FingerprintDatabase::from_survey(site.survey(1.0, &mut rng).unwrap()).unwrap();
    let index = FingerprintIndex::new(database, site.signal_space()).unwrap();
    // seed 002's N_k = 4 and n = 4; on this 3.25 m grid with σ_p = 4 dB the global neighbours
    // reach beyond seed 002's 20 m radius on 7.5 % of the queries, so the radius is 30 m
    let local = LocalWknn {
        radius_m: 30.0,
        ..LocalWknn::default()
    };
    let locator = local.build(&index).unwrap();
    let reference_points = index.database().reference_point_count();
    let (mut same, mut compared, mut error_sum_m) = (0, 0, 0.0);
    let trials = 200u32;
    for _ in 0..trials {
        let truth = [rng.gen_range(20.0..500.0), rng.gen_range(20.0..380.0)];
        // seed 002's online noise, σ_p² = 16 dB²
        let query = site.query(truth, 16.0, &mut rng).unwrap();
        let global = local.knn.locate(&index, &query).unwrap();
        let restricted = locator.locate(&query).unwrap();
        same += usize::from(global.neighbours == restricted.neighbours);
        compared += locator.candidate_count(&query).unwrap();
        error_sum_m += (restricted.fix.position - nalgebra::Vector2::from(truth)).norm();
    }
    let agreement = same as f64 / f64::from(trials);
    let fraction = compared as f64 / (trials as usize * reference_points) as f64;
    println!(
        "grid site: same neighbours {:.1} %, reference points compared {:.2} %, mean error {:.2} m",
        100.0 * agreement,
        100.0 * fraction,
        error_sum_m / f64::from(trials)
    );
    assert!(agreement >= 0.99, "agreement {agreement}");
    assert!(fraction <= 0.05, "L-WKNN compares {fraction} of the reference points");
    // seed 002 reports < 3.1 m on its 10 m grid; this grid is 3.25 m
    assert!(
        error_sum_m / f64::from(trials) < 3.1,
        "mean error {}",
        error_sum_m / f64::from(trials)
    );
}
