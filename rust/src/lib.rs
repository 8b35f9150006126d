//! quadrs engine. This file holds the Python bindings only; the physics lives in the modules.

pub mod config;
pub mod control;
#[path = "gust_stub.rs"]
pub mod gust;
pub mod integrate;
pub mod lane;
pub mod metrics;
pub mod model;
pub mod trajectory;
