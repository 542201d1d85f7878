//! Column sets: the typed views through which a kernel reads and writes queue columns.
//!
//! A kernel's signature names the columns it touches by taking one column set per queue, e.g.
//! `intersect_closest(world, rays: ClosestRays, out: ClosestOut)` where `ClosestRays` holds
//! `RayQueue.{origin, direction, t_max}` as slices and `ClosestOut` holds `HitColumns.{t, prim}`
//! as mutable slices (the kernel sizes the queue through [`Resize`]). [`column_set!`](crate::column_set) declares such a view and, from the
//! same field list, its [`Column`] descriptors (queue, name, bytes per row), which the stage
//! registry ([`crate::schedule::stage`]) collects: the registry cannot disagree with the
//! signatures because both come from one declaration. Each stage declares its kernels with
//! [`kernels!`](crate::kernels!), naming each kernel's column sets: the registry takes kernel
//! names and columns from there.

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

/// A column set whose kernel writes every row of its queue's written columns, in place: what
/// [`Resize`] hands out once the kernel knows the queue's new length, and what the compaction
/// helper ([`super::compact::compact`]) cuts into per-chunk pieces.
pub trait ColumnSet: Sized {
    /// The queue the set borrows.
    type Queue: super::Queue;
    /// How the set borrows it: `&'a mut Queue` for a set of lifetime `'a`.
    type QueueMut: std::ops::DerefMut<Target = Self::Queue>;

    /// Borrows the set's columns of `queue` (the written ones as mutable slices).
    fn of(queue: Self::QueueMut) -> Self;

    /// Rows `..k` and `k..` of every column of the set.
    fn split_at(self, k: usize) -> (Self, Self);
}

/// A written column set whose kernel decides its queue's length: the kernel calls
/// [`Resize::resize`] with the number of rows it will write, which sizes every column of the
/// queue (one length) and gives the set. Columns of the queue the set does not write keep
/// whatever rows they had (a later kernel writes them in place).
#[derive(Debug)]
pub struct Resize<S: ColumnSet> {
    queue: S::QueueMut,
}

impl<S: ColumnSet> Resize<S> {
    /// The queue, to be sized by the kernel.
    #[inline]
    pub fn of(queue: S::QueueMut) -> Self {
        Resize { queue }
    }

    /// Sizes the queue to `n` rows and borrows the set's columns.
    #[inline]
    pub fn resize(mut self, n: usize) -> S {
        super::Queue::resize(&mut *self.queue, n);
        S::of(self.queue)
    }
}

/// A kernel as the stage registry lists it: its name and the column sets it takes, in order.
#[derive(Clone, Copy, Debug)]
pub struct KernelDecl {
    /// The kernel function's name.
    pub name: &'static str,
    /// The `COLUMNS` of each column set the kernel takes.
    pub sets: &'static [&'static [ColumnAccess]],
}

impl KernelDecl {
    /// Every column the kernel touches, set by set.
    pub fn columns(&self) -> impl Iterator<Item = ColumnAccess> + '_ {
        self.sets.iter().flat_map(|s| s.iter().copied())
    }
}

/// Declares a stage's kernels, in the order the schedule calls them, each with the column sets
/// it takes: `const KERNELS = [kernel(SetA, SetB), …];` gives a `&[KernelDecl]`, which the stage
/// registry reads (names and columns). Each name must be a function in scope, so a renamed or
/// removed kernel does not compile.
#[macro_export]
macro_rules! kernels {
    (
        $(#[$meta:meta])*
        $vis:vis const $name:ident = [ $( $kernel:ident ( $($set:ident),* $(,)? ) ),* $(,)? ];
    ) => {
        $(#[$meta])*
        $vis const $name: &[$crate::queue::KernelDecl] = &[$(
            $crate::queue::KernelDecl {
                name: stringify!($kernel),
                sets: &[$($set::COLUMNS),*],
            }
        ),*];
        const _: () = { $( let _ = $kernel; )* };
    };
}

/// Declares a column set: a struct borrowing some columns of one queue (declared with
/// [`queue!`](crate::queue!)), plus its [`ColumnAccess`](crate::queue::ColumnAccess) list
/// (`COLUMNS`) and a constructor `of(queue)`.
///
/// Two forms:
/// - `struct S<'a>: read Queue { a: T, … }` — every column read: fields are `&'a [T]`, and
///   `of(&'a Queue)`.
/// - `struct S<'a>: Queue { read a: T, write b: U, … }` — each column read (`&'a [T]`) or written
///   in place (`&'a mut [U]`, every row of the queue): `of(&'a mut Queue)`; the set is a
///   [`ColumnSet`](crate::queue::ColumnSet), so a kernel that sizes the queue takes it as
///   [`Resize<S>`](crate::queue::Resize).
///
/// Columns are slices either way: a kernel changes rows, never a column's length.
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
                let c = queue.columns();
                Self { $($field: c.$field),* }
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
                let c = queue.columns_mut();
                Self { $($field: c.$field),* }
            }

            /// The set of a kernel that sizes `queue` itself ([`Resize`](crate::queue::Resize)).
            #[inline]
            pub fn resizing(queue: &$a mut $queue) -> $crate::queue::Resize<Self> {
                $crate::queue::Resize::of(queue)
            }
        }
        impl<$a> $crate::queue::ColumnSet for $name<$a> {
            type Queue = $queue;
            type QueueMut = &$a mut $queue;

            #[inline]
            fn of(queue: &$a mut $queue) -> Self {
                $name::of(queue)
            }

            #[inline]
            fn split_at(self, k: usize) -> (Self, Self) {
                $(let $field = $crate::column_set!(@split $mode self.$field, k);)*
                (Self { $($field: $field.0),* }, Self { $($field: $field.1),* })
            }
        }
    };
    (@type read $a:lifetime $ty:ty) => { &$a [$ty] };
    (@type write $a:lifetime $ty:ty) => { &$a mut [$ty] };
    (@split read $e:expr, $k:expr) => { $e.split_at($k) };
    (@split write $e:expr, $k:expr) => { $e.split_at_mut($k) };
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
