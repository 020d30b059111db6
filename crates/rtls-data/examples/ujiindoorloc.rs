//! Fingerprinting on UJIIndoorLoc (train → validation): building and floor hit rates and the
//! 2-D error of KNN, WKNN and L-WKNN, and the signal spaces and neighbour counts we tried.
//!
//! ```sh
//! cargo run --release -p rtls-data --example ujiindoorloc
//! ```
//! Prints the markdown tables of `docs/FINGERPRINTING.md`. Set `RTLS_DATA_DIR` if the datasets
//! are not in `../shared/data`.

use rtls_data::ujiindoorloc::{self, evaluate, locate_all, neighbour_agreement, score, Evaluation, Fingerprint};
use rtls_data::{data_dir, DataError};
use rtls_positioning::fingerprint::{
    FingerprintDatabase, FingerprintIndex, Knn, LocalWknn, SignalDistance, SignalRepresentation, SignalSpace,
};

/// Neighbours of the recommended configuration.
const NEIGHBOURS: usize = 13;

fn main() -> Result<(), DataError> {
    let dir = data_dir();
    let training = ujiindoorloc::load(&dir.join(ujiindoorloc::TRAINING))?;
    let validation = ujiindoorloc::load(&dir.join(ujiindoorloc::VALIDATION))?;
    println!(
        "UJIIndoorLoc: {} training fingerprints (reference points), {} validation queries\n",
        training.len(),
        validation.len()
    );
    // Access-point positions are not in the dataset: estimate them from the survey.
    let database = FingerprintDatabase::from_survey(ujiindoorloc::survey(&training))?.with_estimated_anchors(8)?;

    println!("## Methods (powed representation, Sørensen distance, k = {NEIGHBOURS})\n");
    header();
    let index = FingerprintIndex::new(database.clone(), SignalSpace::powed_sorensen())?;
    let knn = Knn::unweighted(NEIGHBOURS);
    let wknn = Knn::wknn(NEIGHBOURS);
    let local = LocalWknn {
        strongest_anchors: 3,
        radius_m: 40.0,
        knn: wknn,
    };
    let locator = local.build(&index)?;
    // each method locates every query once; scores and agreements reuse the outcomes
    let global = locate_all(&validation, |q| wknn.locate(&index, q));
    let restricted = locate_all(&validation, |q| locator.locate(q));
    row("KNN", &evaluate(&validation, |q| knn.locate(&index, q))?);
    row("WKNN (w ∝ 1/D)", &score(&validation, &global)?);
    row(
        &format!(
            "L-WKNN (N_k = {}, radius {} m)",
            local.strongest_anchors, local.radius_m
        ),
        &score(&validation, &restricted)?,
    );
    let candidates = mean_candidates(&locator, &validation, index.database().reference_point_count());
    println!(
        "\nL-WKNN chooses the same {NEIGHBOURS} neighbours as global WKNN on {:.1} % of the queries; \
         it compares {:.1} % of the reference points per query on average.\n",
        100.0 * neighbour_agreement(&global, &restricted),
        100.0 * candidates
    );

    println!("## L-WKNN: strongest access points N_k and radius (powed, Sørensen, k = {NEIGHBOURS})\n");
    println!("| N_k | radius | same neighbours as global WKNN | reference points compared | mean 2-D error |");
    println!("|---|---|---|---|---|");
    for strongest_anchors in [1, 2, 3, 4] {
        for radius_m in [20.0, 30.0, 40.0, 60.0] {
            let locator = LocalWknn {
                strongest_anchors,
                radius_m,
                knn: wknn,
            }
            .build(&index)?;
            let restricted = locate_all(&validation, |q| locator.locate(q));
            let compared = mean_candidates(&locator, &validation, index.database().reference_point_count());
            println!(
                "| {strongest_anchors} | {radius_m} m | {:.1} % | {:.1} % | {:.2} m |",
                100.0 * neighbour_agreement(&global, &restricted),
                100.0 * compared,
                score(&validation, &restricted)?.mean_error_m
            );
        }
    }
    println!();

    println!("## Signal spaces (WKNN, k = {NEIGHBOURS})\n");
    header();
    let representations = [
        (
            "dBm (positive, floor −104)",
            SignalRepresentation::Positive { floor_dbm: -104.0 },
        ),
        (
            "exponential (α = 24)",
            SignalRepresentation::Exponential {
                floor_dbm: -104.0,
                alpha_db: 24.0,
            },
        ),
        ("powed (β = e)", SignalRepresentation::POWED_WIFI),
    ];
    let distances = [
        ("Euclidean", SignalDistance::Euclidean),
        ("Manhattan", SignalDistance::Manhattan),
        ("Sørensen", SignalDistance::Sorensen),
    ];
    for (representation_name, representation) in representations {
        for (distance_name, distance) in distances {
            let space = SignalSpace {
                representation,
                distance,
            };
            let index = FingerprintIndex::new(database.clone(), space)?;
            let score = evaluate(&validation, |q| wknn.locate(&index, q))?;
            row(&format!("{representation_name}, {distance_name}"), &score);
        }
    }

    println!("\n## Neighbours k (powed, Sørensen)\n");
    header();
    for neighbours in [1, 3, 5, 9, 13, 20, 30] {
        for (name, knn) in [("KNN", Knn::unweighted(neighbours)), ("WKNN", Knn::wknn(neighbours))] {
            row(
                &format!("{name}, k = {neighbours}"),
                &evaluate(&validation, |q| knn.locate(&index, q))?,
            );
        }
    }
    Ok(())
}

fn header() {
    println!("| method | building hits | floor hits | mean 2-D error | median | 75 % | 95 % | failures |");
    println!("|---|---|---|---|---|---|---|---|");
}

fn row(name: &str, e: &Evaluation) {
    println!(
        "| {name} | {:.1} % | {:.1} % | {:.2} m | {:.2} m | {:.2} m | {:.2} m | {} |",
        100.0 * e.building_hit_rate,
        100.0 * e.floor_hit_rate,
        e.mean_error_m,
        e.median_error_m,
        e.p75_error_m,
        e.p95_error_m,
        e.failures.len()
    );
}

/// Mean fraction of reference points an L-WKNN query compares.
fn mean_candidates(
    locator: &rtls_positioning::fingerprint::LocalWknnLocator<'_>,
    queries: &[Fingerprint],
    reference_points: usize,
) -> f64 {
    // a query L-WKNN rejects compares nothing (and is counted as a failure in the tables)
    let total: usize = queries
        .iter()
        .map(|q| locator.candidate_count(&q.query()).unwrap_or(0))
        .sum();
    total as f64 / (queries.len() * reference_points) as f64
}
