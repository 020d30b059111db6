//! Filters: linear, extended and unscented Kalman filters.
