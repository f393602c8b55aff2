//! What an editing problem can be refused for, each naming the constraint or setting and what
//! was expected.

use thiserror::Error;

#[derive(Debug, Error, PartialEq)]
pub enum EditError {
    #[error("unknown experiment `{name}`; expected one of: {known}")]
    UnknownExperiment { name: String, known: String },
    #[error(
        "constraint `{constraint}` is at t = {time} s, outside the simulation (0 to {duration} s)"
    )]
    TimeOutside {
        constraint: String,
        time: f64,
        duration: f64,
    },
    #[error(
        "constraint `{constraint}` asks for ({x}, {y}) m, outside the world's walkable part \
         ({min_x}, {min_y}) to ({max_x}, {max_y}) m, or inside an obstacle"
    )]
    PlaceOutside {
        constraint: String,
        x: f64,
        y: f64,
        min_x: f64,
        min_y: f64,
        max_x: f64,
        max_y: f64,
    },
    #[error("{what} is {value}; a covariance must be a finite number above zero")]
    Covariance { what: String, value: f64 },
    #[error(
        "constraint `{constraint}`'s target does not have the {expected} numbers its operator observes"
    )]
    Shape { constraint: String, expected: usize },
    #[error("{option} applies only to the `rendez-vous` experiment, not `{experiment}`")]
    NotForExperiment { option: String, experiment: String },
    #[error("{what} is {value}; expected {expected}")]
    Setting {
        what: String,
        value: f64,
        expected: String,
    },
}
