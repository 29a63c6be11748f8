//! Obstacles of a 2-D map: which cells block sight and motion, and ray casting between them.

use thiserror::Error;

/// Why an obstacle grid was rejected.
#[derive(Clone, Debug, PartialEq, Error)]
#[error("invalid obstacle grid: {0}")]
pub struct ObstacleGridError(pub String);

/// Which cells of a map block sight: a grid of square cells, row 0 at the bottom (the layout of
/// ROS occupancy maps, which `chronomap_io` converts).
#[derive(Clone, Debug, PartialEq)]
pub struct ObstacleGrid {
    width: usize,
    height: usize,
    resolution: f64,
    origin: [f64; 2],
    blocked: Vec<bool>,
}

impl ObstacleGrid {
    /// A grid of `width × height` cells of side `resolution` (metres) whose cell (0, 0) has its
    /// lower-left corner at `origin`; `blocked` is row-major, row 0 at the bottom.
    ///
    /// # Errors
    /// An [`ObstacleGridError`] for an empty grid, a resolution that is not positive and finite, a
    /// non-finite origin, or `blocked.len() != width · height`.
    pub fn new(
        width: usize,
        height: usize,
        resolution: f64,
        origin: [f64; 2],
        blocked: Vec<bool>,
    ) -> Result<Self, ObstacleGridError> {
        if width == 0 || height == 0 {
            return Err(ObstacleGridError(format!("{width} × {height} cells")));
        }
        if !(resolution.is_finite() && resolution > 0.0) {
            return Err(ObstacleGridError(format!(
                "resolution {resolution} is not a positive number"
            )));
        }
        if !(origin[0].is_finite() && origin[1].is_finite()) {
            return Err(ObstacleGridError(format!(
                "origin {origin:?} is not finite"
            )));
        }
        if width.checked_mul(height) != Some(blocked.len()) {
            return Err(ObstacleGridError(format!(
                "{} cells for {width} × {height}",
                blocked.len()
            )));
        }
        Ok(ObstacleGrid {
            width,
            height,
            resolution,
            origin,
            blocked,
        })
    }

    /// A grid without obstacles.
    ///
    /// # Errors
    /// As [`ObstacleGrid::new`].
    pub fn free(
        width: usize,
        height: usize,
        resolution: f64,
        origin: [f64; 2],
    ) -> Result<Self, ObstacleGridError> {
        let cells = width
            .checked_mul(height)
            .ok_or_else(|| ObstacleGridError(format!("{width} × {height} cells overflow")))?;
        Self::new(width, height, resolution, origin, vec![false; cells])
    }

    /// Cells per row.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Cell side in metres.
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// Lower-left corner of cell (0, 0).
    pub fn origin(&self) -> [f64; 2] {
        self.origin
    }

    /// Marks cell `(column, row)` as blocked (or free); cells outside the grid are ignored.
    pub fn set_blocked(&mut self, column: usize, row: usize, blocked: bool) {
        if column < self.width && row < self.height {
            self.blocked[row * self.width + column] = blocked;
        }
    }

    /// Marks every cell whose centre lies in the rectangle `[min, max]` (metres) as blocked.
    pub fn block_rectangle(&mut self, min: [f64; 2], max: [f64; 2]) {
        for row in 0..self.height {
            for column in 0..self.width {
                let c = self.centre(column, row);
                if (min[0]..=max[0]).contains(&c[0]) && (min[1]..=max[1]).contains(&c[1]) {
                    self.blocked[row * self.width + column] = true;
                }
            }
        }
    }

    /// Whether cell `(column, row)` blocks sight (cells outside the grid do).
    pub fn is_blocked(&self, column: usize, row: usize) -> bool {
        column >= self.width || row >= self.height || self.blocked[row * self.width + column]
    }

    /// Number of blocked cells.
    pub fn blocked_count(&self) -> usize {
        self.blocked.iter().filter(|&&b| b).count()
    }

    /// The cell `(column, row)` containing the point `p`, if it is on the grid.
    pub fn cell_of(&self, p: [f64; 2]) -> Option<(usize, usize)> {
        let column = ((p[0] - self.origin[0]) / self.resolution).floor();
        let row = ((p[1] - self.origin[1]) / self.resolution).floor();
        let inside =
            column >= 0.0 && row >= 0.0 && column < self.width as f64 && row < self.height as f64;
        inside.then_some((column as usize, row as usize))
    }

    /// The centre of cell `(column, row)` in metres.
    pub fn centre(&self, column: usize, row: usize) -> [f64; 2] {
        [
            self.origin[0] + (column as f64 + 0.5) * self.resolution,
            self.origin[1] + (row as f64 + 0.5) * self.resolution,
        ]
    }

    /// Whether the Bresenham line from cell `from` to cell `to` (`(column, row)`, both
    /// included) crosses no blocked cell.
    pub fn line_of_sight(&self, from: (usize, usize), to: (usize, usize)) -> bool {
        let (mut x, mut y) = (from.0 as i64, from.1 as i64);
        let (x1, y1) = (to.0 as i64, to.1 as i64);
        let dx = (x1 - x).abs();
        let dy = -(y1 - y).abs();
        let sx = if x < x1 { 1 } else { -1 };
        let sy = if y < y1 { 1 } else { -1 };
        let mut err = dx + dy;
        loop {
            // x and y stay between the two ends, so they are valid non-negative indices.
            if self.is_blocked(x as usize, y as usize) {
                return false;
            }
            if x == x1 && y == y1 {
                return true;
            }
            let e2 = 2 * err;
            if e2 >= dy {
                err += dy;
                x += sx;
            }
            if e2 <= dx {
                err += dx;
                y += sy;
            }
        }
    }

    /// Whether the point `to` is visible from the point `from`: both on the grid and
    /// [`ObstacleGrid::line_of_sight`] between their cells.
    pub fn visible(&self, from: [f64; 2], to: [f64; 2]) -> bool {
        match (self.cell_of(from), self.cell_of(to)) {
            (Some(a), Some(b)) => self.line_of_sight(a, b),
            _ => false,
        }
    }

    /// Whether some blocked cell has its centre within `radius` of `p`. Cells beyond the grid
    /// count as obstacles (nothing is known there).
    pub fn obstacle_within(&self, p: [f64; 2], radius: f64) -> bool {
        let r = self.resolution;
        // Cell centres are at origin + (i + 0.5) r.
        let lo = |k: usize| ((p[k] - radius - self.origin[k]) / r - 0.5).ceil();
        let hi = |k: usize| ((p[k] + radius - self.origin[k]) / r - 0.5).floor();
        let (x0, x1, y0, y1) = (lo(0), hi(0), lo(1), hi(1));
        if x0 < 0.0 || y0 < 0.0 || x1 >= self.width as f64 || y1 >= self.height as f64 {
            return true;
        }
        let (x0, x1, y0, y1) = (x0 as usize, x1 as usize, y0 as usize, y1 as usize);
        for row in y0..=y1 {
            let dy = self.origin[1] + (row as f64 + 0.5) * r - p[1];
            for column in x0..=x1 {
                let dx = self.origin[0] + (column as f64 + 0.5) * r - p[0];
                if self.blocked[row * self.width + column] && dx * dx + dy * dy <= radius * radius {
                    return true;
                }
            }
        }
        false
    }
}
