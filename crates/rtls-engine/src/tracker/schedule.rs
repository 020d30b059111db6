//! Seed 003's adaptive node scheduling in the tracker (`[scheduling]` in the site): after each
//! reported update of a confirmed or coasting track, its position predicted one cycle ahead
//! picks next cycle's task nodes and edge monitors ([`TaskScheduler`]); a
//! [`Event::Schedule`] names them whenever they change, so only those readers need to wake.

use std::sync::Arc;

use super::output::{Event, Output};
use crate::error::{EngineError, Result};
use crate::scheduling::{Cell, Layout, Node, TaskScheduler};
use crate::site::Site;

/// The site's scheduling layout: one node per reader named in a cell (in order of first
/// mention), the cells with their node indices, and each node's reader id.
///
/// # Errors
/// [`EngineError::InvalidParameter`] naming the field (`cells`, `cells.nodes`, …) for a
/// layout [`Layout::new`] refuses, or a reader without a position in the plane.
pub(crate) fn scheduling_layout(site: &Site) -> Result<Option<(Layout, Vec<String>)>> {
    let Some(settings) = &site.scheduling else {
        return Ok(None);
    };
    let mut ids: Vec<String> = Vec::new();
    let mut nodes = Vec::new();
    let mut cells = Vec::new();
    for cell in &settings.cells {
        let mut members = Vec::new();
        for id in &cell.readers {
            let index = match ids.iter().position(|known| known == id) {
                Some(index) => index,
                None => {
                    let reader = site.reader(id).ok_or(EngineError::InvalidParameter {
                        name: "cells.readers",
                        reason: "names a reader the site does not have",
                    })?;
                    let p = reader.position_xyz_m();
                    ids.push(id.clone());
                    nodes.push(Node {
                        id: id.clone(),
                        position_m: [p[0], p[1]],
                    });
                    ids.len() - 1
                }
            };
            members.push(index);
        }
        cells.push(Cell {
            min_m: cell.min_m,
            max_m: cell.max_m,
            nodes: members,
        });
    }
    Ok(Some((Layout::new(nodes, cells)?, ids)))
}

/// The scheduling the tracks share.
#[derive(Debug, Clone)]
pub(crate) struct Scheduling {
    layout: Layout,
    scheduler: TaskScheduler,
    /// Reader id of each layout node.
    reader_ids: Vec<Arc<str>>,
    cycle_s: f64,
}

/// A track's nodes for the next cycle: its task nodes and the firing set last reported.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub(crate) struct TrackSchedule {
    task_nodes: Vec<usize>,
    /// The task-node and monitor sets last reported, ascending.
    reported: Option<(Vec<usize>, Vec<usize>)>,
}

impl Scheduling {
    /// The scheduling of `site`, `None` without a `[scheduling]` section.
    ///
    /// # Errors
    /// As [`scheduling_layout`] and [`TaskScheduler::new`].
    pub(crate) fn new(site: &Site) -> Result<Option<Self>> {
        let (Some(settings), Some((layout, ids))) = (&site.scheduling, scheduling_layout(site)?) else {
            return Ok(None);
        };
        Ok(Some(Self {
            layout,
            scheduler: TaskScheduler::new(settings.task_nodes, settings.edge_margin_m)?.with_neighbour_handover(),
            reader_ids: ids.iter().map(|id| Arc::from(id.as_str())).collect(),
            cycle_s: settings.cycle_s,
        }))
    }

    /// Schedules a track at `position_m` moving at `velocity_mps` (time `time_s`): the
    /// prediction one cycle ahead `p + v T` decides its task nodes (a new track takes the
    /// nearest nodes of its cell); a change of task nodes or monitors is reported.
    ///
    /// # Errors
    /// [`EngineError::InvalidParameter`] for a non-finite position.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn update(
        &self,
        tag: &Arc<str>,
        schedule: &mut TrackSchedule,
        time_s: f64,
        position_m: [f64; 2],
        velocity_mps: [f64; 2],
        out: &mut Output,
    ) -> Result<()> {
        // p⁻ = p + v T
        let predicted_m = [
            position_m[0] + velocity_mps[0] * self.cycle_s,
            position_m[1] + velocity_mps[1] * self.cycle_s,
        ];
        if schedule.task_nodes.is_empty() {
            schedule.task_nodes = self.scheduler.initial(&self.layout, position_m)?;
        }
        let decision = self.scheduler.decide(&self.layout, &schedule.task_nodes, predicted_m)?;
        schedule.task_nodes.clone_from(&decision.task_nodes);
        // reported when the sets change (not their nearest-first order)
        let sorted = |nodes: &[usize]| {
            let mut nodes = nodes.to_vec();
            nodes.sort_unstable();
            nodes
        };
        let sets = (sorted(&decision.task_nodes), sorted(&decision.monitors));
        if schedule.reported.as_ref() != Some(&sets) {
            let firing = (decision.task_nodes.clone(), decision.monitors.clone());
            let names = |nodes: &[usize]| nodes.iter().map(|&n| Arc::clone(&self.reader_ids[n])).collect();
            out.events.push(Event::Schedule {
                tag: Arc::clone(tag),
                time_s,
                task_nodes: names(&firing.0),
                monitors: names(&firing.1),
            });
            schedule.reported = Some(sets);
        }
        Ok(())
    }
}
