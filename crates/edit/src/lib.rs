//! Optimal crowd editing (Allain, Courty and Corpetti, "Optimal crowd editing", Graphical
//! Models 2014): a crowd simulated with the social-force model is edited towards what a user
//! asks for (two people meeting at a place and time, a density in an area, a velocity field, a
//! whirl) by optimal control: the model error eps(t) and initial-condition error eps_0 that
//! minimise the cost of eq. 6, their gradient coming from one backward (adjoint) integration.
//!
//! Read in this order: `model` (the forces and their derivatives), `integrate` (Runge-Kutta
//! and its exact tangent-linear and adjoint), `observe` (the observation operators), `cost`
//! (the problem and J), `descent` (local and global descents), `experiments` (the paper's five).

pub mod cost;
pub mod descent;
pub mod error;
pub mod experiments;
pub mod field;
pub mod integrate;
pub mod model;
pub mod neighbours;
pub mod observe;
pub mod quasi_newton;
pub mod world;

pub use cost::{Constraint, CostParts, Covariances, Objective, Problem};
pub use descent::{CONVERGED, CONVERGED_OVER, Descent, Iteration, Outcome, Stop, solve};
pub use error::EditError;
pub use integrate::{Run, Timeline};
pub use model::{Character, Linearisation, Model, Repulsion};
pub use world::{Rect, World};
