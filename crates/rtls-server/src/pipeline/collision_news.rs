//! A collision transition on its way to the hub's subscribers, and its omlox `CollisionEvent`.
//!
//! The collision thread finds a transition at every update of a colliding trackable (the spec's
//! `colliding` at each update); an omlox `CollisionEvent` — a name-based UUID (SHA-1), two
//! timestamps, two 17-vertex polygons — costs far more than finding it. So the hub carries the
//! transition, and the event is built when a `collision_events` subscriber first asks for it
//! ([`CollisionNews::event`]), once, shared by every subscriber. With no subscriber it is
//! never built.

use std::sync::{Arc, OnceLock};

use crate::convert::uuid_for;
use crate::omlox::collision::{Side, Transition};
use crate::omlox::time::format_timestamp;
use crate::omlox::{Collision, CollisionEvent, CollisionType, Point, Polygon};

/// Vertices of the polygon that draws a trackable's judged disc in a `Collision`.
const DISC_VERTICES: usize = 16;

/// A pair's collision started, goes on or ended ([`Transition`]), with its omlox event built
/// on first use.
#[derive(Debug, Clone, PartialEq)]
pub struct CollisionNews {
    /// What happened.
    pub transition: Transition,
    /// The omlox event, once built (`None`: a time not representable, logged once).
    event: OnceLock<Option<Arc<CollisionEvent>>>,
}

impl CollisionNews {
    /// News of `transition`; its event is not built yet.
    #[must_use]
    pub fn new(transition: Transition) -> Self {
        Self {
            transition,
            event: OnceLock::new(),
        }
    }

    /// The tags whose updates placed the two trackables, in the event's order.
    #[must_use]
    pub fn tags(&self) -> [&str; 2] {
        [&self.transition.trigger.provider_id, &self.transition.other.provider_id]
    }

    /// The two trackables' ids, in the event's order.
    #[must_use]
    pub fn trackables(&self) -> [&str; 2] {
        [&self.transition.trigger.id, &self.transition.other.id]
    }

    /// The omlox `CollisionEvent`, built on the first call; `None` when a time cannot be
    /// written as a timestamp (logged at the first call).
    pub fn event(&self) -> Option<&Arc<CollisionEvent>> {
        self.event
            .get_or_init(|| match collision_event(&self.transition) {
                Ok(event) => Some(Arc::new(event)),
                Err(e) => {
                    tracing::warn!(error = %e, "collision event not representable");
                    None
                }
            })
            .as_ref()
    }
}

/// The omlox event of a transition: a name-based id (the same transition, replayed, has the
/// same id), timestamps from the records' clock.
///
/// # Errors
/// [`crate::ServerError::Unrepresentable`] when a time cannot be written as a timestamp.
pub(crate) fn collision_event(transition: &Transition) -> crate::Result<CollisionEvent> {
    let kind = transition.kind;
    let name = format!(
        "{}|{}|{:?}|{}",
        transition.trigger.id, transition.other.id, kind, transition.time_s
    );
    let time = format_timestamp(transition.time_s, "collision_time")?;
    Ok(CollisionEvent {
        id: uuid_for("collision-event", &name),
        collision_type: kind,
        start_time: Some(format_timestamp(transition.start_s, "start_time")?),
        end_time: (kind == CollisionType::CollisionEnd).then(|| time.clone()),
        collision_time: (kind == CollisionType::Colliding).then_some(time),
        collisions: vec![collision(&transition.trigger), collision(&transition.other)],
        collision_area: transition.area_m.map(|[x, y]| Point {
            coordinates: vec![x, y],
        }),
        center_distance: Some(transition.distance_m),
    })
}

/// One side as an omlox `Collision`: its position and its judged disc as a polygon.
fn collision(side: &Side) -> Collision {
    let centre = [
        side.coordinates.first().copied().unwrap_or(0.0),
        side.coordinates.get(1).copied().unwrap_or(0.0),
    ];
    let ring: Vec<Vec<f64>> = (0..=DISC_VERTICES)
        .map(|i| {
            // the last vertex repeats the first: a closed ring
            let angle = std::f64::consts::TAU * (i % DISC_VERTICES) as f64 / DISC_VERTICES as f64;
            vec![
                centre[0] + side.extent_m * angle.cos(),
                centre[1] + side.extent_m * angle.sin(),
            ]
        })
        .collect();
    Collision {
        id: side.id.clone(),
        object_type: "trackable".into(),
        position: Some(Point {
            coordinates: side.coordinates.clone(),
        }),
        geometry: (side.extent_m > 0.0).then(|| Polygon {
            coordinates: vec![ring],
        }),
        floor: Some(side.floor),
    }
}
