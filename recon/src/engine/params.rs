//! One flat vector holds every trainable number; modules own ranges of it. Gradients, Adam
//! moments and checkpoints share the layout, so a backend only has to move one buffer.

use std::ops::Range;

/// Which learning-rate group a range of parameters belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Group {
    /// Dense network weights and biases.
    Network,
    /// One level's hash-grid feature table (level 0 the coarsest).
    Grid {
        /// The level.
        level: usize,
    },
    /// The NeuS inverse-standard-deviation parameter.
    Variance,
    /// Parameters nothing reads (a coarse hash-grid level's table past its cells' corners):
    /// their gradient is always zero, and Adam leaves them as they are.
    Unused,
}

/// The layout of the flat parameter vector, filled module by module.
#[derive(Clone, Debug, Default)]
pub struct ParamLayout {
    ranges: Vec<(Range<usize>, Group)>,
    len: usize,
}

impl ParamLayout {
    /// Reserve `len` parameters in `group`; returns their offset.
    pub fn reserve(&mut self, len: usize, group: Group) -> usize {
        let offset = self.len;
        self.len += len;
        self.ranges.push((offset..self.len, group));
        offset
    }

    /// Total number of parameters.
    pub fn len(&self) -> usize {
        self.len
    }

    /// True when nothing is reserved.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The reserved ranges with their groups, in order.
    pub fn ranges(&self) -> &[(Range<usize>, Group)] {
        &self.ranges
    }
}
