//! The assignment solver against brute force over every assignment.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::assignment::{solve_assignment, CostMatrix};
use crate::error::EngineError;

/// The minimum of `Σ cᵢⱼ + Σ c₀ᵢ` over every feasible assignment, by depth-first enumeration
/// (each row: unassigned, or any free column with a finite cost).
fn brute_force(costs: &CostMatrix, unassigned: &[f64]) -> f64 {
    fn visit(costs: &CostMatrix, unassigned: &[f64], row: usize, used: &mut [bool], sum: f64, best: &mut f64) {
        if row == costs.rows() {
            *best = best.min(sum);
            return;
        }
        visit(costs, unassigned, row + 1, used, sum + unassigned[row], best);
        for column in 0..costs.columns() {
            let c = costs.get(row, column).unwrap();
            if !used[column] && c.is_finite() {
                used[column] = true;
                visit(costs, unassigned, row + 1, used, sum + c, best);
                used[column] = false;
            }
        }
    }
    let mut best = f64::INFINITY;
    visit(costs, unassigned, 0, &mut vec![false; costs.columns()], 0.0, &mut best);
    best
}

/// Checks that `assignment` is feasible and that its reported cost is its actual cost.
fn check_consistent(costs: &CostMatrix, unassigned: &[f64], assignment: &super::assignment::Assignment) -> f64 {
    let mut sum = 0.0;
    let mut taken = vec![false; costs.columns()];
    for (row, column) in assignment.row_to_column.iter().enumerate() {
        match column {
            None => sum += unassigned[row],
            Some(c) => {
                assert!(!taken[*c], "column {c} assigned twice");
                taken[*c] = true;
                let cost = costs.get(row, *c).unwrap();
                assert!(cost.is_finite(), "forbidden pair ({row}, {c}) assigned");
                assert_eq!(assignment.column_to_row[*c], Some(row));
                sum += cost;
            }
        }
    }
    for (column, row) in assignment.column_to_row.iter().enumerate() {
        assert_eq!(row.is_some(), taken[column], "column {column}");
    }
    assert!(
        (sum - assignment.total_cost).abs() < 1e-9,
        "{sum} vs {}",
        assignment.total_cost
    );
    sum
}

#[test]
fn matches_brute_force_on_random_rectangular_matrices_with_forbidden_pairs() {
    let mut rng = ChaCha8Rng::seed_from_u64(20_261_122);
    let mut cases = 0;
    let mut some_unassigned = 0;
    for rows in 0..=7 {
        for columns in 0..=7 {
            for _ in 0..12 {
                // costs in [−5, 20), about a third forbidden; some rows unassigned cheaply
                let forbidden_share = rng.gen_range(0.0..0.6);
                let data: Vec<f64> = (0..rows * columns)
                    .map(|_| {
                        if rng.gen_bool(forbidden_share) {
                            f64::INFINITY
                        } else {
                            rng.gen_range(-5.0..20.0)
                        }
                    })
                    .collect();
                let costs = CostMatrix::new(rows, columns, data).unwrap();
                let unassigned: Vec<f64> = (0..rows).map(|_| rng.gen_range(0.0..15.0)).collect();
                let solved = solve_assignment(&costs, &unassigned).unwrap();
                let cost = check_consistent(&costs, &unassigned, &solved);
                let best = brute_force(&costs, &unassigned);
                assert!(
                    (cost - best).abs() < 1e-9,
                    "{rows}×{columns}: solver {cost}, brute force {best}"
                );
                some_unassigned += usize::from(solved.row_to_column.iter().any(Option::is_none) && columns >= rows);
                cases += 1;
            }
        }
    }
    assert_eq!(cases, 8 * 8 * 12);
    // the non-assignment option was exercised where a full assignment would have been possible
    assert!(some_unassigned > 50, "{some_unassigned}");
}

#[test]
fn integer_costs_with_ties_match_brute_force() {
    // Small integer costs make many optimal assignments tie: the cost must still be optimal.
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for _ in 0..300 {
        let rows = rng.gen_range(1..=7);
        let columns = rng.gen_range(1..=7);
        let data: Vec<f64> = (0..rows * columns)
            .map(|_| {
                if rng.gen_bool(0.2) {
                    f64::INFINITY
                } else {
                    f64::from(rng.gen_range(0..4))
                }
            })
            .collect();
        let costs = CostMatrix::new(rows, columns, data).unwrap();
        let unassigned = vec![2.0; rows];
        let solved = solve_assignment(&costs, &unassigned).unwrap();
        let cost = check_consistent(&costs, &unassigned, &solved);
        assert_eq!(cost, brute_force(&costs, &unassigned));
    }
}

#[test]
fn hand_checked_cases() {
    let inf = f64::INFINITY;
    // 3 × 3 classic: optimum 0→1 (1), 1→0 (2), 2→2 (2) = 5 (the diagonal costs 4 + 4 + 2 = 10)
    let costs = CostMatrix::new(3, 3, vec![4.0, 1.0, 3.0, 2.0, 4.0, 5.0, 3.0, 2.0, 2.0]).unwrap();
    let best = solve_assignment(&costs, &[100.0; 3]).unwrap();
    assert_eq!(best.row_to_column, vec![Some(1), Some(0), Some(2)]);
    assert_eq!(best.total_cost, 5.0);
    // every pair forbidden: everything unassigned
    let none = CostMatrix::forbidden(2, 3).unwrap();
    let best = solve_assignment(&none, &[1.5, 2.5]).unwrap();
    assert_eq!(best.row_to_column, vec![None, None]);
    assert_eq!(best.column_to_row, vec![None, None, None]);
    assert_eq!(best.total_cost, 4.0);
    // more rows than columns: the two rows competing for column 0 — the one that gains more takes it
    let tall = CostMatrix::new(3, 1, vec![1.0, 0.0, inf]).unwrap();
    let best = solve_assignment(&tall, &[5.0, 3.0, 1.0]).unwrap();
    // row 0 gains 4 by taking column 0, row 1 gains 3
    assert_eq!(best.row_to_column, vec![Some(0), None, None]);
    assert_eq!(best.total_cost, 1.0 + 3.0 + 1.0);
    // negative non-assignment costs are fine: leaving everything unassigned is best
    let best = solve_assignment(&costs, &[-1.0; 3]).unwrap();
    assert_eq!(best.row_to_column, vec![None; 3]);
    // empty problems
    let empty = CostMatrix::new(0, 4, vec![]).unwrap();
    let best = solve_assignment(&empty, &[]).unwrap();
    assert!(best.row_to_column.is_empty());
    assert_eq!(best.column_to_row, vec![None; 4]);
}

#[test]
fn bad_input_is_an_error_naming_the_field() {
    let name = |e: EngineError| match e {
        EngineError::InvalidParameter { name, .. } => name,
        other => panic!("unexpected {other}"),
    };
    assert_eq!(name(CostMatrix::new(2, 2, vec![1.0; 3]).unwrap_err()), "costs");
    assert_eq!(name(CostMatrix::new(1, 2, vec![1.0, f64::NAN]).unwrap_err()), "costs");
    assert_eq!(
        name(CostMatrix::new(1, 1, vec![f64::NEG_INFINITY]).unwrap_err()),
        "costs"
    );
    let mut costs = CostMatrix::forbidden(2, 2).unwrap();
    assert_eq!(name(costs.set(2, 0, 1.0).unwrap_err()), "row");
    assert_eq!(name(costs.set(0, 2, 1.0).unwrap_err()), "column");
    assert_eq!(costs.get(5, 0), None);
    assert_eq!(
        name(solve_assignment(&costs, &[1.0]).unwrap_err()),
        "non_assignment_costs"
    );
    assert_eq!(
        name(solve_assignment(&costs, &[1.0, f64::INFINITY]).unwrap_err()),
        "non_assignment_costs"
    );
    let message = solve_assignment(&costs, &[1.0]).unwrap_err().to_string();
    assert!(message.contains("one non-assignment cost per row"), "{message}");
}
