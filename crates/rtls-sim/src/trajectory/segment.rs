//! One piece of a planar truth trajectory and its exact closed-form kinematics.

/// The motion law of one segment.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Motion {
    /// `a = 0`, `v = v₀`.
    ConstantVelocity,
    /// `v = 0`, position held.
    Stopped,
    /// Constant speed, velocity rotating at `ω` rad/s (counter-clockwise positive).
    Turn {
        /// Turn rate `ω` in rad/s.
        rate_rad_s: f64,
    },
    /// Constant acceleration `a` in m/s².
    ConstantAcceleration {
        /// `a = [ax, ay]` in m/s².
        acceleration_mps2: [f64; 2],
    },
}

/// Position, velocity and acceleration at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Kinematics {
    /// `p` in m.
    pub position_m: [f64; 2],
    /// `v` in m/s.
    pub velocity_mps: [f64; 2],
    /// `a` in m/s².
    pub acceleration_mps2: [f64; 2],
}

/// A segment `[start_s, start_s + duration_s]` of a trajectory with its initial state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Segment {
    /// Time at which the segment starts, s.
    pub start_s: f64,
    /// Length of the segment, s (> 0).
    pub duration_s: f64,
    /// Position at the start, m.
    pub start_position_m: [f64; 2],
    /// Velocity at the start, m/s (zero for [`Motion::Stopped`]).
    pub start_velocity_mps: [f64; 2],
    /// The motion law.
    pub motion: Motion,
}

impl Segment {
    /// Time at which the segment ends, s.
    pub fn end_s(&self) -> f64 {
        self.start_s + self.duration_s
    }

    /// Exact kinematics `tau_s` seconds after the segment's start (`0 ≤ τ ≤ duration`).
    pub fn state(&self, tau_s: f64) -> Kinematics {
        let [px, py] = self.start_position_m;
        let [vx, vy] = self.start_velocity_mps;
        let t = tau_s;
        match self.motion {
            Motion::ConstantVelocity => Kinematics {
                // p(τ) = p₀ + v₀ τ
                position_m: [px + vx * t, py + vy * t],
                velocity_mps: [vx, vy],
                acceleration_mps2: [0.0, 0.0],
            },
            Motion::Stopped => Kinematics {
                // p(τ) = p₀, v = 0
                position_m: [px, py],
                velocity_mps: [0.0, 0.0],
                acceleration_mps2: [0.0, 0.0],
            },
            Motion::ConstantAcceleration {
                acceleration_mps2: [ax, ay],
            } => Kinematics {
                // p(τ) = p₀ + v₀ τ + a τ²/2
                position_m: [px + vx * t + 0.5 * ax * t * t, py + vy * t + 0.5 * ay * t * t],
                // v(τ) = v₀ + a τ
                velocity_mps: [vx + ax * t, vy + ay * t],
                acceleration_mps2: [ax, ay],
            },
            Motion::Turn { rate_rad_s: w } => {
                // θ = ω τ
                let theta = w * t;
                let (sin_t, cos_t) = theta.sin_cos();
                // v(τ) = R(θ) v₀
                let v = [cos_t * vx - sin_t * vy, sin_t * vx + cos_t * vy];
                // ∫₀^τ R(ωs) ds = [[S, −C], [C, S]] with S = sin θ / ω, C = (1 − cos θ)/ω
                // (C written as 2 sin²(θ/2)/ω to avoid cancellation; ω = 0 is a straight line).
                let (s_int, c_int) = if w == 0.0 {
                    (t, 0.0)
                } else {
                    let half = (0.5 * theta).sin();
                    (sin_t / w, 2.0 * half * half / w)
                };
                Kinematics {
                    // p(τ) = p₀ + [[S, −C], [C, S]] v₀
                    position_m: [px + s_int * vx - c_int * vy, py + c_int * vx + s_int * vy],
                    velocity_mps: v,
                    // a = ω × v = ω [−v_y, v_x] (centripetal)
                    acceleration_mps2: [-w * v[1], w * v[0]],
                }
            }
        }
    }

    /// Exact kinematics at the segment's end.
    pub fn end_state(&self) -> Kinematics {
        self.state(self.duration_s)
    }
}
