//! The training losses: each term's name, a value per term ([`PerTerm`], for weights and
//! logged values), and the per-ray and per-sample losses with their derivatives (the geometric
//! loss is in [`crate::geometric`]). Normalisation by batch counts and weights is left to the
//! caller. Adding a loss is a [`Term`], its weight in the presets, and its computation in the
//! trainer; logs, reports and the command line list terms by name.

use serde::de::{Deserializer, MapAccess, Visitor};
use serde::ser::{SerializeMap, Serializer};
use serde::{Deserialize, Serialize};
use std::ops::{Index, IndexMut};

/// A term of the training loss.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Term {
    /// L1 on S0, S1, S2: the photometric cue.
    Photometric,
    /// AoP tangent-space consistency: the geometric cue.
    Geometric,
    /// Mask binary cross-entropy.
    Mask,
    /// Eikonal regulariser.
    Eikonal,
    /// Mean absolute SDF Laplacian (Neuralangelo's curvature loss, against hash-grid noise).
    Curvature,
}

impl Term {
    /// Every term, in the order they are summed and logged.
    pub const ALL: [Term; 5] = [Term::Photometric, Term::Geometric, Term::Mask, Term::Eikonal, Term::Curvature];
}

impl std::fmt::Display for Term {
    /// The term's name in logs and files: its serde name.
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        self.serialize(f)
    }
}

/// One value per loss term; stored as a map from the terms' names (a term missing from a
/// stored map reads as the default, zero).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PerTerm<T>([T; Term::ALL.len()]);

impl<T: Copy> PerTerm<T> {
    /// From a function of the term.
    pub fn from_fn(f: impl Fn(Term) -> T) -> Self {
        Self(Term::ALL.map(f))
    }

    /// `(term, value)` in [`Term::ALL`] order.
    pub fn iter(&self) -> impl Iterator<Item = (Term, T)> + '_ {
        Term::ALL.iter().map(|&t| (t, self[t]))
    }
}

impl<T> Index<Term> for PerTerm<T> {
    type Output = T;
    fn index(&self, term: Term) -> &T {
        &self.0[term as usize]
    }
}

impl<T> IndexMut<Term> for PerTerm<T> {
    fn index_mut(&mut self, term: Term) -> &mut T {
        &mut self.0[term as usize]
    }
}

impl<T: Serialize> Serialize for PerTerm<T> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let mut map = serializer.serialize_map(Some(Term::ALL.len()))?;
        for (term, value) in Term::ALL.iter().zip(&self.0) {
            map.serialize_entry(&term, value)?;
        }
        map.end()
    }
}

impl<'de, T: Deserialize<'de> + Default + Copy> Deserialize<'de> for PerTerm<T> {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct TermMap<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de> + Default + Copy> Visitor<'de> for TermMap<T> {
            type Value = PerTerm<T>;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a map from loss-term names to values")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<PerTerm<T>, A::Error> {
                let mut out = PerTerm::<T>::default();
                while let Some((term, value)) = map.next_entry::<Term, T>()? {
                    out[term] = value;
                }
                Ok(out)
            }
        }
        deserializer.deserialize_map(TermMap(std::marker::PhantomData))
    }
}

/// Opacity clamp of the mask loss (NeuS).
const CLAMP: f32 = 1e-3;

/// Binary cross-entropy of accumulated `opacity` against the mask; returns (loss, d/d opacity),
/// the derivative zero where the opacity is clamped.
pub fn mask_bce(opacity: f32, inside: bool) -> (f32, f32) {
    let a = opacity.clamp(CLAMP, 1.0 - CLAMP);
    let m = inside as u8 as f32;
    let loss = -(m * a.ln() + (1.0 - m) * (1.0 - a).ln());
    let d = if (CLAMP..=1.0 - CLAMP).contains(&opacity) { -(m / a - (1.0 - m) / (1.0 - a)) } else { 0.0 };
    (loss, d)
}

/// L1 distance; returns (loss, d/d prediction).
pub fn l1(prediction: f32, target: f32) -> (f32, f32) {
    let diff = prediction - target;
    (diff.abs(), diff.signum())
}

/// Eikonal term `(|g| - 1)^2`; returns (loss, d/d g).
pub fn eikonal(g: [f32; 3]) -> (f32, [f32; 3]) {
    let len = (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]).sqrt().max(1e-8);
    let s = 2.0 * (len - 1.0) / len;
    ((len - 1.0) * (len - 1.0), g.map(|v| s * v))
}

/// Curvature term `|laplacian|`; returns (loss, d/d laplacian).
pub fn curvature(laplacian: f32) -> (f32, f32) {
    (laplacian.abs(), laplacian.signum())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn per_term_values_are_stored_by_name() {
        let mut weights = PerTerm::from_fn(|t| t as u8 as f32);
        weights[Term::Eikonal] = 0.1;
        let text = serde_json::to_string(&weights).unwrap();
        assert_eq!(text, r#"{"photometric":0.0,"geometric":1.0,"mask":2.0,"eikonal":0.1,"curvature":4.0}"#);
        assert_eq!(serde_json::from_str::<PerTerm<f32>>(&text).unwrap(), weights);
        let partial: PerTerm<f32> = serde_json::from_str(r#"{"mask": 1.0}"#).unwrap();
        assert_eq!(partial.iter().map(|(_, v)| v).sum::<f32>(), 1.0);
        assert!(serde_json::from_str::<PerTerm<f32>>(r#"{"sharpness": 1.0}"#).is_err());
    }
}
