//! The turntable's angle error: what the angle encoder reads against where the rail is.
//!
//! An angle encoder's disc mounted off its axis by `e`, or a gear's eccentricity, makes the
//! angle read off by `e/R` once a turn; an elliptic disc twice a turn. With the step angle
//! `φ = 2π k/N` the rail really stands at
//!
//! ```text
//! a(φ) = alpha0 + φ + ε(φ),     ε(φ) = Σ_h (c_h cos hφ + s_h sin hφ)        (angle error)
//! ```
//!
//! over a set of orders `h` ([`HarmonicOrders`]). A constant error is `alpha0` itself, so
//! orders start at 1. Every rail angle of the engine goes through [`AngleError::at`]: the
//! models fit the coefficients ([`super::model::turntable`]), the correction applies them
//! ([`super::correct::Corrector`]). `∂a/∂c_h = cos hφ`, `∂a/∂s_h = sin hφ`: a coefficient's
//! Jacobian column is `alpha0`'s times its basis function.

use std::fmt;

/// A set of harmonic orders `1..=63`, in increasing order.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub struct HarmonicOrders(u64);

/// Orders that make no set of harmonics ([`HarmonicOrders::new`]): the order given.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("an angle harmonic's order must be from 1 to {max} (0 is alpha0 itself), each once, got {0}", max = HarmonicOrders::MAX)]
pub struct InvalidOrder(pub i64);

impl HarmonicOrders {
    /// The highest order.
    pub const MAX: u32 = 63;
    /// No harmonics: the angle encoder taken as exact.
    pub const NONE: HarmonicOrders = HarmonicOrders(0);

    /// The orders given, each `1..=MAX` and once.
    pub fn new(orders: &[i64]) -> Result<Self, InvalidOrder> {
        let mut bits = 0u64;
        for &h in orders {
            if !(1..=i64::from(Self::MAX)).contains(&h) || bits & (1 << h) != 0 {
                return Err(InvalidOrder(h));
            }
            bits |= 1 << h;
        }
        Ok(HarmonicOrders(bits))
    }

    /// The orders, increasing.
    pub fn iter(self) -> impl Iterator<Item = u32> + Clone {
        (1..=Self::MAX).filter(move |h| self.0 & (1 << h) != 0)
    }

    /// How many orders.
    pub fn len(self) -> usize {
        self.0.count_ones() as usize
    }

    pub fn is_empty(self) -> bool {
        self.0 == 0
    }

    pub fn contains(self, h: u32) -> bool {
        h <= Self::MAX && self.0 & (1 << h) != 0
    }

    /// The orders as the parameter `calibration.angle_harmonics` holds them.
    pub fn to_vec(self) -> Vec<i64> {
        self.iter().map(i64::from).collect()
    }

    /// `cos hφ, sin hφ` for every order, in the coefficients' order
    /// (`[cos h₁φ, sin h₁φ, cos h₂φ, ...]`).
    pub fn basis(self, phi: f64) -> impl Iterator<Item = f64> {
        self.iter().flat_map(move |h| {
            let (s, c) = (f64::from(h) * phi).sin_cos();
            [c, s]
        })
    }
}

impl fmt::Display for HarmonicOrders {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let orders: Vec<String> = self.iter().map(|h| h.to_string()).collect();
        f.write_str(&orders.join(", "))
    }
}

/// The angle error `ε(φ)` of a turntable: its orders and coefficients
/// `[c_h₁, s_h₁, c_h₂, s_h₂, ...]`, radians.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AngleError {
    orders: HarmonicOrders,
    coefficients: Vec<f64>,
}

/// Coefficients that do not go with their orders ([`AngleError::new`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InvalidAngleError {
    #[error("{coefficients} angle coefficients for {orders} harmonic orders: expected two (cosine, sine) an order")]
    Count { orders: usize, coefficients: usize },
    #[error("angle coefficient {index} is {value}: a finite angle in radians of at most 0.1 rad is expected")]
    Value { index: usize, value: f64 },
}

/// The largest coefficient taken, radians (5.7°): an angle encoder off by more is broken,
/// not mounted off.
pub const MAX_COEFFICIENT: f64 = 0.1;

impl AngleError {
    /// No angle error.
    pub const NONE: AngleError = AngleError { orders: HarmonicOrders::NONE, coefficients: Vec::new() };

    /// The error of `orders` with `coefficients` (two an order, finite, at most
    /// [`MAX_COEFFICIENT`]).
    pub fn new(orders: HarmonicOrders, coefficients: Vec<f64>) -> Result<Self, InvalidAngleError> {
        if coefficients.len() != 2 * orders.len() {
            return Err(InvalidAngleError::Count { orders: orders.len(), coefficients: coefficients.len() });
        }
        if let Some((index, &value)) =
            coefficients.iter().enumerate().find(|(_, c)| !(c.is_finite() && c.abs() <= MAX_COEFFICIENT))
        {
            return Err(InvalidAngleError::Value { index, value });
        }
        Ok(AngleError { orders, coefficients })
    }

    /// The orders fitted, every coefficient 0.
    pub fn zero(orders: HarmonicOrders) -> Self {
        AngleError { orders, coefficients: vec![0.0; 2 * orders.len()] }
    }

    pub fn orders(&self) -> HarmonicOrders {
        self.orders
    }

    pub fn coefficients(&self) -> &[f64] {
        &self.coefficients
    }

    pub fn is_none(&self) -> bool {
        self.coefficients.iter().all(|c| *c == 0.0)
    }

    /// `ε(φ)`, radians.
    #[inline]
    pub fn at(&self, phi: f64) -> f64 {
        if self.coefficients.is_empty() {
            return 0.0;
        }
        self.orders.basis(phi).zip(&self.coefficients).map(|(b, c)| b * c).sum()
    }

    /// The largest `|ε|` round the turn (on 720 angles), radians.
    pub fn peak(&self) -> f64 {
        (0..720).map(|i| self.at(std::f64::consts::TAU * f64::from(i) / 720.0).abs()).fold(0.0, f64::max)
    }
}

/// The names of the coefficients, as `covariance_names` gives them after the five of the
/// tracer: `angle_c1, angle_s1, angle_c2, ...`.
pub fn coefficient_names(orders: HarmonicOrders) -> Vec<String> {
    orders.iter().flat_map(|h| [format!("angle_c{h}"), format!("angle_s{h}")]).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn orders_are_a_set_from_one_up() {
        let o = HarmonicOrders::new(&[4, 1, 2]).unwrap();
        assert_eq!(o.iter().collect::<Vec<_>>(), vec![1, 2, 4]);
        assert_eq!(o.len(), 3);
        assert_eq!(o.to_string(), "1, 2, 4");
        assert_eq!(HarmonicOrders::new(&[0]), Err(InvalidOrder(0)));
        assert_eq!(HarmonicOrders::new(&[2, 2]), Err(InvalidOrder(2)));
        assert_eq!(HarmonicOrders::new(&[64]), Err(InvalidOrder(64)));
        assert_eq!(
            InvalidOrder(0).to_string(),
            "an angle harmonic's order must be from 1 to 63 (0 is alpha0 itself), each once, got 0"
        );
        assert_eq!(coefficient_names(o), ["angle_c1", "angle_s1", "angle_c2", "angle_s2", "angle_c4", "angle_s4"]);
    }

    #[test]
    fn the_error_sums_its_harmonics() {
        let o = HarmonicOrders::new(&[1, 3]).unwrap();
        let e = AngleError::new(o, vec![1e-3, -2e-3, 5e-4, 0.0]).unwrap();
        let phi = 0.7_f64;
        assert_relative_eq!(e.at(phi), 1e-3 * phi.cos() - 2e-3 * phi.sin() + 5e-4 * (3.0 * phi).cos(), epsilon = 1e-18);
        assert!(e.peak() > 1.7e-3 && e.peak() < 2.8e-3, "{}", e.peak());
        assert_eq!(AngleError::new(o, vec![0.0; 3]), Err(InvalidAngleError::Count { orders: 2, coefficients: 3 }));
        assert!(matches!(AngleError::new(o, vec![0.0, 0.0, 0.5, 0.0]), Err(InvalidAngleError::Value { index: 2, .. })));
        assert_eq!(AngleError::NONE.at(1.0), 0.0);
    }
}
