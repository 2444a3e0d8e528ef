//! Value types: element kinds, shapes over grids, SSA values.

/// Element kind of a value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Elem {
    /// A real number.
    Real,
    /// A complex number.
    Complex,
    /// A truth value (from comparisons; consumed by `select`).
    Bool,
}

/// Index of a grid in [`Function::grids`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct GridId(pub u32);

/// Shape of a value: a scalar, or one element per point of a grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shape {
    /// One number.
    Scalar,
    /// One number per grid point.
    Grid(GridId),
}

/// Type of an IR value.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Ty {
    /// Element kind.
    pub elem: Elem,
    /// Shape.
    pub shape: Shape,
}

impl Ty {
    /// A real scalar.
    pub const REAL: Ty = Ty { elem: Elem::Real, shape: Shape::Scalar };
    /// A complex scalar.
    pub const COMPLEX: Ty = Ty { elem: Elem::Complex, shape: Shape::Scalar };
    /// The same shape with another element kind.
    pub fn with_elem(self, elem: Elem) -> Ty {
        Ty { elem, shape: self.shape }
    }
}

/// An SSA value: the index of the instruction that defines it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Value(pub u32);

impl Value {
    /// As an index into [`Function::insts`].
    pub fn index(self) -> usize {
        self.0 as usize
    }
}
