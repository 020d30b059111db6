//! Range-free positioning: fixes from which anchors hear a tag (and how strongly), without
//! calibrated ranges — seed 000's baselines.
//!
//! - [`centroid`], [`weighted_centroid`] — the (weighted) mean of the anchors that hear the
//!   tag; weights from RSSI ([`rssi_weights`], [`rssi_weighted_centroid`]) or from ranges
//!   ([`range_weights`], [`range_weighted_centroid`]) after Blumenthal et al. (2007).
//! - [`DvHop`] — DV-Hop over a multi-hop network (Niculescu & Nath).

mod centroid;
pub use centroid::{
    centroid, range_weighted_centroid, range_weights, rssi_weighted_centroid, rssi_weights, weighted_centroid,
};

mod dv_hop;
pub use dv_hop::{unit_disk_edges, DvHop, DvHopOptions};
