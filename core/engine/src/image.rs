//! Camera image streams: what a simulator renders for a demo and a dataset stores, carried through
//! generation untouched (the engine itself never looks at pixels).

/// The pixels of one image stream, all steps row-major.
#[derive(Debug, Clone, PartialEq)]
pub enum Pixels {
    /// RGB, `uint8` (robomimic's `<camera>_image`).
    Rgb(Vec<u8>),
    /// Depth as `float32` (robosuite's `<camera>_depth`: the normalized depth buffer in `[0, 1]`).
    Depth(Vec<f32>),
}

/// One camera's images: per-step shape `[height, width, channels]` and every step's pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageStream {
    /// Shape of one step's image, `[height, width, channels]`.
    pub shape: [usize; 3],
    /// Every step's pixels.
    pub pixels: Pixels,
}

impl ImageStream {
    /// Number of values in all steps.
    #[must_use]
    pub fn len(&self) -> usize {
        match &self.pixels {
            Pixels::Rgb(p) => p.len(),
            Pixels::Depth(p) => p.len(),
        }
    }

    /// True with no pixels.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of whole steps held.
    #[must_use]
    pub fn steps(&self) -> usize {
        self.len() / self.shape.iter().product::<usize>().max(1)
    }

    /// Step `t`'s RGB pixels (`None` for depth or past the end).
    #[must_use]
    pub fn rgb_frame(&self, t: usize) -> Option<&[u8]> {
        let per_step = self.shape.iter().product::<usize>();
        match &self.pixels {
            Pixels::Rgb(p) => p.get(t * per_step..(t + 1) * per_step),
            Pixels::Depth(_) => None,
        }
    }
}
