//! Fingerprinting on the recorded UJIIndoorLoc data (train → validation): the reader, the
//! accuracy of WKNN in the recommended signal space against the published kNN baselines, and
//! how closely L-WKNN with estimated access-point positions follows global WKNN.
//!
//! Data: `../shared/data/ujiindoorloc` (Torres-Sospedra et al., IPIN 2014; CC BY 4.0), or
//! `$RTLS_DATA_DIR/ujiindoorloc`. The full tables: `cargo run --release -p rtls-data --example
//! ujiindoorloc` (docs/FINGERPRINTING.md).

use rtls_data::data_dir;
use rtls_data::ujiindoorloc::{self, evaluate, locate_all, neighbour_agreement, score, Fingerprint};
use rtls_positioning::fingerprint::{
    FingerprintDatabase, FingerprintIndex, Knn, LocalWknn, SignalDistance, SignalRepresentation, SignalSpace,
};

fn load() -> (Vec<Fingerprint>, Vec<Fingerprint>) {
    let dir = data_dir();
    let training = ujiindoorloc::load(&dir.join(ujiindoorloc::TRAINING)).unwrap();
    let validation = ujiindoorloc::load(&dir.join(ujiindoorloc::VALIDATION)).unwrap();
    (training, validation)
}

#[test]
fn ujiindoorloc_wknn_beats_the_published_knn_baselines_and_l_wknn_follows_it() {
    let (training, validation) = load();
    assert_eq!((training.len(), validation.len()), (19_937, 1_111));
    // every record hears something, and the sentinel 100 never reaches a reading
    assert!(training
        .iter()
        .chain(&validation)
        .flat_map(|f| &f.readings_dbm)
        .all(|&(ap, rssi)| ap < 520 && (-104.0..=0.0).contains(&rssi)));

    let database = FingerprintDatabase::from_survey(ujiindoorloc::survey(&training))
        .unwrap()
        .with_estimated_anchors(8)
        .unwrap();
    // 520 access points, of which the training survey hears 465: only those get a position
    let located = database.anchors_m().iter().filter(|a| a.is_some()).count();
    assert_eq!(located, 465);

    // The recommended space: powed representation, Sørensen distance, k = 13.
    let index = FingerprintIndex::new(database.clone(), SignalSpace::powed_sorensen()).unwrap();
    let wknn = Knn::wknn(13);
    let global = locate_all(&validation, |q| wknn.locate(&index, q));
    let wknn_score = score(&validation, &global).unwrap();
    assert!(wknn_score.failures.is_empty(), "{:?}", &wknn_score.failures[..1]);
    assert!(wknn_score.building_hit_rate >= 0.995, "{wknn_score:?}");
    assert!(wknn_score.floor_hit_rate >= 0.94, "{wknn_score:?}");
    // published kNN baselines on this split: 7.2–7.9 m
    assert!(wknn_score.mean_error_m < 7.0, "{wknn_score:?}");

    // The raw dBm space with the Euclidean distance is clearly worse (why the space matters).
    let dbm = SignalSpace {
        representation: SignalRepresentation::Positive { floor_dbm: -104.0 },
        distance: SignalDistance::Euclidean,
    };
    let dbm_index = FingerprintIndex::new(database, dbm).unwrap();
    let dbm_score = evaluate(&validation, |q| wknn.locate(&dbm_index, q)).unwrap();
    assert!(dbm_score.mean_error_m > wknn_score.mean_error_m + 1.0, "{dbm_score:?}");
    assert!(dbm_score.floor_hit_rate < wknn_score.floor_hit_rate, "{dbm_score:?}");

    // L-WKNN with estimated access-point positions: same neighbours as global WKNN on almost
    // every query while comparing a fraction of the reference points.
    let locator = LocalWknn {
        strongest_anchors: 3,
        radius_m: 40.0,
        knn: wknn,
    }
    .build(&index)
    .unwrap();
    let restricted = locate_all(&validation, |q| locator.locate(q));
    let agreement = neighbour_agreement(&global, &restricted);
    assert!(agreement >= 0.97, "agreement {agreement}");
    let compared: usize = validation
        .iter()
        .map(|q| locator.candidate_count(&q.query()).unwrap())
        .sum();
    let fraction = compared as f64 / (validation.len() * index.database().reference_point_count()) as f64;
    assert!(fraction < 0.16, "L-WKNN compares {fraction} of the reference points");
    // the 2.1 % of queries with other neighbours cost 0.23 m of mean error (6.70 vs 6.47 m)
    let local_score = score(&validation, &restricted).unwrap();
    assert!(
        (local_score.mean_error_m - wknn_score.mean_error_m).abs() < 0.3,
        "{local_score:?}"
    );
}
