//! A fixed-size raster over a grid of cells, filled cell by cell while a grid's rows are read,
//! so that memory does not grow with the grid (what the maps are drawn from).

/// Largest raster side, cells: grids finer than this are down-sampled (last cell in index order
/// wins), which is finer than the figure's pixels anyway.
pub const RASTER_MAX: usize = 1200;

/// A fixed-size raster over an `nx × ny` cell grid (`x` index fastest in the plot's `x`).
#[derive(Debug, Clone)]
pub struct Raster<T: Copy> {
    nx: usize,
    ny: usize,
    rx: usize,
    ry: usize,
    data: Vec<T>,
}

impl<T: Copy> Raster<T> {
    /// A raster for `nx × ny` cells, at most [`RASTER_MAX`] per side, filled with `fill`.
    pub fn new(nx: usize, ny: usize, fill: T) -> Self {
        let (rx, ry) = (nx.clamp(1, RASTER_MAX), ny.clamp(1, RASTER_MAX));
        Raster {
            nx: nx.max(1),
            ny: ny.max(1),
            rx,
            ry,
            data: vec![fill; rx * ry],
        }
    }

    /// Sets cell `(ix, iy)`.
    pub fn set(&mut self, ix: usize, iy: usize, v: T) {
        let cx = (ix * self.rx / self.nx).min(self.rx - 1);
        let cy = (iy * self.ry / self.ny).min(self.ry - 1);
        self.data[cy * self.rx + cx] = v;
    }

    /// Every stored value.
    pub fn values(&self) -> impl Iterator<Item = T> + '_ {
        self.data.iter().copied()
    }

    /// The raster's size, cells `(x, y)` (at most [`RASTER_MAX`] each).
    pub fn raster_size(&self) -> (usize, usize) {
        (self.rx, self.ry)
    }

    /// The value of raster cell `(cx, cy)` (`cx < raster_size().0`, `cy < raster_size().1`).
    pub fn raster_cell(&self, cx: usize, cy: usize) -> T {
        self.data[cy * self.rx + cx]
    }
}
