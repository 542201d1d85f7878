//! [`queue!`](crate::queue!): a queue declared once, as its columns; everything else is generated.
//!
//! A queue is a structure of arrays whose columns always have one length. The columns are
//! private: rows are added and removed only for every column at once ([`Queue::resize`],
//! `clear`, `push`), and kernels borrow columns as slices (through column sets,
//! [`crate::column_set!`]), which can change rows but never their number. So "every column has
//! one length" holds by construction, not by convention.
//!
//! ```
//! use glam::Vec3;
//! wavefront::queue! {
//!     /// Two columns.
//!     pub struct Pairs {
//!         /// A point.
//!         point: Vec3,
//!         /// A count.
//!         count: u32,
//!     }
//!     /// One row of `Pairs`.
//!     pub struct Pair;
//! }
//! wavefront::column_set! {
//!     /// Writes points.
//!     pub struct Points<'a>: Pairs { write point: Vec3 }
//! }
//! let mut q = Pairs::default();
//! q.push(Pair { point: Vec3::ZERO, count: 3 });
//! Points::of(&mut q).point[0] = Vec3::ONE;
//! q.resize(4);
//! assert_eq!((q.len(), q.count(), q.get(0).point), (4, &[3, 0, 0, 0][..], Vec3::ONE));
//! assert_eq!(Pairs::ROW_BYTES, 16);
//! ```
//!
//! A column set's written columns are slices: a kernel cannot push onto one column and leave the
//! others behind.
//!
//! ```compile_fail
//! use glam::Vec3;
//! wavefront::queue! {
//!     /// Two columns.
//!     pub struct Pairs {
//!         /// A point.
//!         point: Vec3,
//!         /// A count.
//!         count: u32,
//!     }
//!     /// One row of `Pairs`.
//!     pub struct Pair;
//! }
//! wavefront::column_set! {
//!     /// Writes points.
//!     pub struct Points<'a>: Pairs { write point: Vec3 }
//! }
//! let mut q = Pairs::default();
//! let set = Points::of(&mut q);
//! set.point.push(Vec3::ZERO); // slices have no `push`
//! ```

/// What every [`queue!`](crate::queue!) generates and the column-set machinery needs.
pub trait Queue: Default {
    /// The queue's type name (`RayQueue`, …), as column descriptors name it.
    const NAME: &'static str;
    /// Every column: name and bytes per row, in declaration order.
    const COLUMNS: &'static [super::Column];
    /// Bytes per row across all columns (for bandwidth figures).
    const ROW_BYTES: usize;

    /// Number of rows (of every column).
    fn len(&self) -> usize;

    /// True when the queue holds no rows.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Sets every column to `n` rows: rows past `n` are dropped; new rows are the columns'
    /// defaults where the queue never had them, else what they last held (a kernel that sizes a
    /// queue overwrites the rows it writes).
    fn resize(&mut self, n: usize);

    /// Each column's length, in declaration order (always all equal: what tests check).
    fn column_lens(&self) -> Vec<usize>;
}

/// Declares a queue: a struct whose private `Vec` columns always have one length, a row type
/// (`push`, `get`), and in the invoking module the views `Columns<'a>` (every column as a slice)
/// and `ColumnsMut<'a>` (every column as a mutable slice) through which column sets borrow it.
/// One queue per module (the views have fixed names).
///
/// Generated on the queue: `len`, `is_empty`, `clear`, `resize(n)`, `reset(n)` (`n` default
/// rows), `push(row)`, `get(i)`, `capacity`, a read accessor per column returning its slice,
/// `columns`, `columns_mut`, and through [`Queue`](crate::queue::Queue) `NAME`, `COLUMNS`, `ROW_BYTES`,
/// `column_lens`.
#[macro_export]
macro_rules! queue {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident {
            $( $(#[$fmeta:meta])* $field:ident: $ty:ty ),+ $(,)?
        }
        $(#[$imeta:meta])*
        $ivis:vis struct $item:ident;
    ) => {
        $(#[$meta])*
        #[derive(Clone, Debug, Default)]
        $vis struct $name {
            $( $field: ::std::vec::Vec<$ty>, )+
            /// Rows in use: every column's first `rows_in_use` elements. The `Vec`s keep the
            /// rows a queue once had (their high-water mark, all initialised), so a queue that
            /// shrinks and grows again, as every wave's queues do, rewrites no row it does not
            /// use.
            rows_in_use: usize,
        }

        $(#[$imeta])*
        #[derive(Clone, Copy, Debug, PartialEq)]
        $ivis struct $item {
            $( $(#[$fmeta])* pub $field: $ty, )+
        }

        #[doc = concat!("Every column of a [`", stringify!($name), "`] as a slice.")]
        #[derive(Clone, Copy, Debug)]
        $vis struct Columns<'a> {
            $( #[doc = concat!("`", stringify!($name), ".", stringify!($field), "`")]
            pub $field: &'a [$ty], )+
        }

        #[doc = concat!("Every column of a [`", stringify!($name), "`] as a mutable slice: rows ")]
        /// can be changed, never added or removed.
        #[derive(Debug)]
        $vis struct ColumnsMut<'a> {
            $( #[doc = concat!("`", stringify!($name), ".", stringify!($field), "`")]
            pub $field: &'a mut [$ty], )+
        }

        impl $name {
            /// Bytes per row across all columns (for bandwidth figures).
            pub const ROW_BYTES: usize = 0 $( + ::std::mem::size_of::<$ty>() )+;

            /// Number of rows.
            #[inline]
            pub fn len(&self) -> usize {
                self.rows_in_use
            }

            /// True when the queue holds no rows.
            #[inline]
            pub fn is_empty(&self) -> bool {
                self.len() == 0
            }

            /// Removes all rows, keeping the allocations.
            pub fn clear(&mut self) {
                self.rows_in_use = 0;
            }

            /// Sets every column to `n` rows. Rows beyond any length the queue had are the
            /// columns' defaults; rows within it keep whatever they last held (a kernel that
            /// sizes a queue overwrites the rows it writes; [`Self::reset`] for default rows).
            pub fn resize(&mut self, n: usize) {
                $( if self.$field.len() < n {
                    self.$field.resize(n, ::std::default::Default::default());
                } )+
                self.rows_in_use = n;
            }

            /// Resets to `n` default rows, keeping the allocations.
            pub fn reset(&mut self, n: usize) {
                self.resize(n);
                $( self.$field[..n].fill(::std::default::Default::default()); )+
            }

            /// Appends one row.
            pub fn push(&mut self, row: $item) {
                let n = self.rows_in_use;
                $( if self.$field.len() > n {
                    self.$field[n] = row.$field;
                } else {
                    self.$field.push(row.$field);
                } )+
                self.rows_in_use = n + 1;
            }

            /// Row `i`.
            pub fn get(&self, i: usize) -> $item {
                let c = self.columns();
                $item { $( $field: c.$field[i], )+ }
            }

            /// Rows the queue holds without reallocating (the least of its columns').
            pub fn capacity(&self) -> usize {
                [$( self.$field.capacity() ),+].into_iter().min().unwrap_or(0)
            }

            /// Every column as a slice.
            #[inline]
            pub fn columns(&self) -> Columns<'_> {
                let n = self.rows_in_use;
                Columns { $( $field: &self.$field[..n], )+ }
            }

            /// Every column as a mutable slice (what written column sets borrow).
            #[inline]
            pub fn columns_mut(&mut self) -> ColumnsMut<'_> {
                let n = self.rows_in_use;
                ColumnsMut { $( $field: &mut self.$field[..n], )+ }
            }

            $(
                $(#[$fmeta])*
                #[inline]
                pub fn $field(&self) -> &[$ty] {
                    &self.$field[..self.rows_in_use]
                }
            )+
        }

        impl $crate::queue::Queue for $name {
            const NAME: &'static str = stringify!($name);
            const COLUMNS: &'static [$crate::queue::Column] = &[$(
                $crate::queue::Column {
                    queue: stringify!($name),
                    name: stringify!($field),
                    bytes: ::std::mem::size_of::<$ty>(),
                }
            ),+];
            const ROW_BYTES: usize = $name::ROW_BYTES;

            #[inline]
            fn len(&self) -> usize {
                $name::len(self)
            }

            fn resize(&mut self, n: usize) {
                $name::resize(self, n)
            }

            fn column_lens(&self) -> ::std::vec::Vec<usize> {
                let c = self.columns();
                vec![$( c.$field.len() ),+]
            }
        }
    };
}

// The test queues use only part of what the macros generate.
#[cfg(test)]
#[allow(dead_code)]
mod tests {
    use super::Queue;
    use glam::Vec3;

    crate::queue! {
        /// A test queue.
        pub struct Probe {
            /// Vectors.
            v: Vec3,
            /// Flags.
            flag: bool,
            /// Counts.
            n: u32,
        }
        /// One row.
        pub struct ProbeRow;
    }

    fn row(i: u32) -> ProbeRow {
        ProbeRow {
            v: Vec3::splat(i as f32),
            flag: i % 2 == 1,
            n: i,
        }
    }

    #[test]
    fn every_operation_keeps_one_length() {
        let mut q = Probe::default();
        let one = |q: &Probe| {
            let lens = q.column_lens();
            assert_eq!(lens.len(), 3);
            assert!(lens.iter().all(|&l| l == q.len()), "{lens:?}");
        };
        one(&q);
        q.push(row(1));
        q.push(row(2));
        one(&q);
        assert_eq!(q.get(1), row(2));
        q.resize(5);
        one(&q);
        assert_eq!(
            (q.len(), q.n(), q.flag()[4]),
            (5, &[1, 2, 0, 0, 0][..], false)
        );
        q.resize(1);
        one(&q);
        assert_eq!(q.v(), &[Vec3::ONE]);
        let cap = q.capacity();
        q.clear();
        one(&q);
        assert!(q.is_empty());
        assert!(
            cap >= 5 && q.capacity() == cap,
            "clear keeps the allocation"
        );
        q.reset(3);
        assert_eq!(q.n(), &[0, 0, 0]);
        one(&q);
    }

    #[test]
    fn regrown_rows_are_not_rewritten_and_reset_rows_are_defaults() {
        let mut q = Probe::default();
        for i in 1..=4 {
            q.push(row(i));
        }
        q.resize(1);
        q.push(row(9));
        q.resize(4);
        assert_eq!(q.n(), &[1, 9, 3, 4], "resize keeps the rows it had");
        q.clear();
        q.resize(6);
        assert_eq!(q.n(), &[1, 9, 3, 4, 0, 0], "new rows are defaults");
        q.reset(5);
        assert_eq!(q.n(), &[0; 5]);
        assert_eq!(
            q.get(4),
            ProbeRow {
                v: Vec3::ZERO,
                flag: false,
                n: 0
            }
        );
    }

    #[test]
    fn mutable_columns_change_rows_not_lengths() {
        let mut q = Probe::default();
        q.resize(3);
        let c = q.columns_mut();
        c.n.copy_from_slice(&[7, 8, 9]);
        c.flag[1] = true;
        assert_eq!(
            q.get(1),
            ProbeRow {
                v: Vec3::ZERO,
                flag: true,
                n: 8
            }
        );
        assert_eq!(q.columns().n, &[7, 8, 9]);
    }

    #[test]
    fn descriptors_and_row_bytes_come_from_the_columns() {
        assert_eq!(Probe::NAME, "Probe");
        let names: Vec<_> = Probe::COLUMNS
            .iter()
            .map(|c| (c.queue, c.name, c.bytes))
            .collect();
        assert_eq!(
            names,
            vec![("Probe", "v", 12), ("Probe", "flag", 1), ("Probe", "n", 4)]
        );
        assert_eq!(Probe::ROW_BYTES, 17);
        assert_eq!(<Probe as Queue>::ROW_BYTES, 17);
    }
}
