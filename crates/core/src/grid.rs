//! Raster grids in image order.

/// A `width x height` raster stored row by row, row 0 at the north edge (image order), so that
/// pixel `(x, y)` of a layer is cell `(x, y)` of every grid built from it.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid<T> {
    width: u32,
    height: u32,
    data: Vec<T>,
}

impl<T: Clone> Grid<T> {
    /// A grid filled with `value`.
    pub fn filled(width: u32, height: u32, value: T) -> Grid<T> {
        Grid {
            width,
            height,
            data: vec![value; width as usize * height as usize],
        }
    }
}

impl<T> Grid<T> {
    /// A grid over `data` in row order; `None` when the length does not fit the size.
    pub fn from_vec(width: u32, height: u32, data: Vec<T>) -> Option<Grid<T>> {
        (data.len() == width as usize * height as usize).then_some(Grid {
            width,
            height,
            data,
        })
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    pub fn get(&self, x: u32, y: u32) -> &T {
        &self.data[y as usize * self.width as usize + x as usize]
    }

    pub fn row(&self, y: u32) -> &[T] {
        let w = self.width as usize;
        &self.data[y as usize * w..(y as usize + 1) * w]
    }

    pub fn as_slice(&self) -> &[T] {
        &self.data
    }

    pub fn as_mut_slice(&mut self) -> &mut [T] {
        &mut self.data
    }
}
