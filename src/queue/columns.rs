//! Column sets: the typed views through which a kernel reads and writes queue columns.
//!
//! A kernel's signature names the columns it touches by taking one column set per queue, e.g.
//! `intersect_closest(world, rays: ClosestRays, out: ClosestOut)` where `ClosestRays` holds
//! `RayQueue.{origin, direction, t_max}` as slices and `ClosestOut` holds `HitColumns.{t, prim}`
//! as growable columns. [`column_set!`](crate::column_set) declares such a view and, from the
//! same field list, its [`Column`] descriptors (queue, name, bytes per row), which the stage
//! registry ([`crate::schedule::stage`]) collects: the registry cannot disagree with the
//! signatures because both come from one declaration.

/// One column of a queue: which queue, which column, how many bytes per row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Column {
    /// The queue's type name (`RayQueue`, `HitColumns`, `HitQueue`, `ShadowQueue`, …).
    pub queue: &'static str,
    /// The column's field name.
    pub name: &'static str,
    /// Bytes per row.
    pub bytes: usize,
}

impl std::fmt::Display for Column {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}.{}", self.queue, self.name)
    }
}

/// Whether a kernel reads or writes a column.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Access {
    /// Read only.
    Read,
    /// Written (resized and filled, or updated in place).
    Write,
}

/// A column and how a kernel uses it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ColumnAccess {
    /// Read or write.
    pub access: Access,
    /// The column.
    pub column: Column,
}

/// Declares a column set: a struct borrowing some columns of one queue, plus its
/// [`ColumnAccess`] list (`COLUMNS`) and a constructor `of(queue)`.
///
/// Two forms:
/// - `struct S<'a>: read Queue { a: T, … }` — every column read: fields are `&'a [T]`, and
///   `of(&'a Queue)`.
/// - `struct S<'a>: Queue { read a: T, write b: U, … }` — each column read (`&'a [T]`) or written
///   (`&'a mut Vec<U>`, which the kernel sizes): `of(&'a mut Queue)`.
#[macro_export]
macro_rules! column_set {
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident<$a:lifetime>: read $queue:ident {
            $($field:ident: $ty:ty),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Clone, Copy, Debug)]
        $vis struct $name<$a> {
            $(#[doc = concat!("`", stringify!($queue), ".", stringify!($field), "` (read)")]
            pub $field: &$a [$ty],)*
        }
        impl<$a> $name<$a> {
            /// The columns this set touches.
            pub const COLUMNS: &'static [$crate::queue::ColumnAccess] = &[$(
                $crate::column_set!(@entry read $queue $field $ty)
            ),*];

            /// Borrows these columns of `queue`.
            #[inline]
            pub fn of(queue: &$a $queue) -> Self {
                Self { $($field: &queue.$field),* }
            }
        }
    };
    (
        $(#[$meta:meta])*
        $vis:vis struct $name:ident<$a:lifetime>: $queue:ident {
            $($mode:ident $field:ident: $ty:ty),* $(,)?
        }
    ) => {
        $(#[$meta])*
        #[derive(Debug)]
        $vis struct $name<$a> {
            $(#[doc = concat!("`", stringify!($queue), ".", stringify!($field), "` (", stringify!($mode), ")")]
            pub $field: $crate::column_set!(@type $mode $a $ty),)*
        }
        impl<$a> $name<$a> {
            /// The columns this set touches.
            pub const COLUMNS: &'static [$crate::queue::ColumnAccess] = &[$(
                $crate::column_set!(@entry $mode $queue $field $ty)
            ),*];

            /// Borrows these columns of `queue` (the written ones mutably).
            #[inline]
            pub fn of(queue: &$a mut $queue) -> Self {
                Self { $($field: $crate::column_set!(@borrow $mode queue $field)),* }
            }
        }
    };
    (@type read $a:lifetime $ty:ty) => { &$a [$ty] };
    (@type write $a:lifetime $ty:ty) => { &$a mut Vec<$ty> };
    (@borrow read $q:ident $f:ident) => { &$q.$f };
    (@borrow write $q:ident $f:ident) => { &mut $q.$f };
    (@entry $mode:ident $queue:ident $field:ident $ty:ty) => {
        $crate::queue::ColumnAccess {
            access: $crate::column_set!(@access $mode),
            column: $crate::queue::Column {
                queue: stringify!($queue),
                name: stringify!($field),
                bytes: ::std::mem::size_of::<$ty>(),
            },
        }
    };
    (@access read) => { $crate::queue::Access::Read };
    (@access write) => { $crate::queue::Access::Write };
}
