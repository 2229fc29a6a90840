//! # rotorid-core
//!
//! The physics and kernels of rotorid, without Python: a rigid rotor on two bearings (4 DOF,
//! q = [x1, x2, y1, y2]), its batched forced response, the identification of the bearing
//! coefficients from imbalance or impact responses, the modal analysis, and the keyphasor-based
//! order processing of raw recordings. Conventions follow the report TRC-RD-1-01 (De Santiago &
//! San Andrés, 2001); every quantity is SI.
//!
//! All entry points are batched over points (speeds or frequencies), write into caller-provided
//! output slices, run in parallel on rayon's pool, and check their arguments first: a wrong
//! length or value is a [`CoreError`], never a panic.
//!
//! ```
//! use rotorid_core::{forced, Rotor, C64};
//! // NSF-rig-like rotor: m, I_T, I_p, l1, l2
//! let rotor = Rotor::from_slice(&[30.7, 0.6, 0.06, 0.14, 0.14]).unwrap();
//! let k = [3e6, 0.0, 0.0, 3e6, 3e6, 0.0, 0.0, 3e6]; // [bearing][i][j], N/m
//! let c = [2e3, 0.0, 0.0, 2e3, 2e3, 0.0, 0.0, 2e3]; // N s/m
//! let w = [100.0];
//! let force = [C64::new(1.0, 0.0), C64::new(1.0, 0.0), C64::new(0.0, 0.0), C64::new(0.0, 0.0)];
//! let mut q = [C64::new(0.0, 0.0); 4];
//! let singular = forced::forced_response(&rotor, &k, &c, &w, &w, &force, 1, &mut q).unwrap();
//! assert_eq!(singular, 0);
//! assert!(q[0].norm() > 0.0);
//! ```

pub mod bounds;
pub mod covariance;
pub mod eig8;
pub mod error;
pub mod forced;
pub mod identify;
pub mod lanes;
pub mod lsq;
pub mod modal;
pub mod model;
pub mod order;
pub mod pedestal;
pub mod pedestal_cov;
pub mod par;
pub mod pedestal_fit;
pub mod revolution_blocks;
pub mod series;
pub mod student_t;
pub mod study;
pub mod timesim;

pub use error::CoreError;
pub use model::{Rotor, C64};
