!> Global numbers of a rank's items (its owned nodes, its cells) kept as runs: items that
!> follow each other in the local order with consecutive global numbers form a run, stored
!> as its first item and first number (a grid row is one run, or a few where holes cut it),
!> so the numbers cost a few integers a row instead of 8 bytes an item.
module iem_number_runs
  use iem_kinds, only: wp, i8
  implicit none
  private
  public :: number_runs_t

  !> Items 1..n_items in n runs: run r holds the items first(r) .. first(r + 1) - 1
  !> (first(n + 1) = n_items + 1), numbered from gid(r) on; runs ascending in both.
  type :: number_runs_t
    integer :: n = 0, n_items = 0
    integer, allocatable :: first(:)
    integer(i8), allocatable :: gid(:)
    !> n / n_items: the first guess of the run that holds an item.
    real(wp) :: scale = 0.0_wp
  contains
    procedure :: init => number_runs_init
    procedure :: add => number_runs_add
    procedure :: run_of => number_runs_run_of
    procedure :: number => number_runs_number
    procedure :: numbers => number_runs_numbers
    procedure :: table => number_runs_table
    procedure :: item_of => number_runs_item_of
    procedure :: free => number_runs_free
  end type number_runs_t

contains

  !> Room for at most max_runs runs, none yet.
  pure subroutine number_runs_init(this, max_runs)
    class(number_runs_t), intent(inout) :: this
    integer, intent(in) :: max_runs
    call this%free()
    allocate(this%first(max_runs + 1), this%gid(max_runs))
    this%first(1) = 1
  end subroutine number_runs_init

  !> Append the next item, numbered g: it starts a run unless it continues the last one
  !> (force_new: it starts one anyway). Returns the run it joined.
  pure subroutine number_runs_add(this, g, force_new, r)
    class(number_runs_t), intent(inout) :: this
    integer(i8), intent(in) :: g
    logical, intent(in) :: force_new
    integer, intent(out) :: r
    logical :: new
    new = this%n == 0 .or. force_new
    if (.not. new) new = g /= this%gid(this%n) + (this%n_items + 1 - this%first(this%n))
    if (new) then
      this%n = this%n + 1
      this%first(this%n) = this%n_items + 1
      this%gid(this%n) = g
    end if
    this%n_items = this%n_items + 1
    this%first(this%n + 1) = this%n_items + 1
    this%scale = real(this%n, wp)/this%n_items
    r = this%n
  end subroutine number_runs_add

  !> The run that holds item k (1..n_items): runs of equal length (a rectangle's rows) are
  !> found at the first guess, others by bisection on its side.
  pure integer function number_runs_run_of(this, k) result(r)
    class(number_runs_t), intent(in) :: this
    integer, intent(in) :: k
    r = min(max(1 + int(real(k - 1, wp)*this%scale), 1), this%n)
    if (this%first(r) > k) then
      r = last_at_or_below(this%first(1:r - 1), k)
    else if (this%first(r + 1) <= k) then
      r = r + last_at_or_below(this%first(r + 1:this%n), k)
    end if
  end function number_runs_run_of

  !> Global number of item k.
  pure integer(i8) function number_runs_number(this, k) result(g)
    class(number_runs_t), intent(in) :: this
    integer, intent(in) :: k
    integer :: r
    r = this%run_of(k)
    g = this%gid(r) + (k - this%first(r))
  end function number_runs_number

  !> The runs as t(:, r) = (first item, its number, items in the run).
  pure function number_runs_table(this) result(t)
    class(number_runs_t), intent(in) :: this
    integer(i8), allocatable :: t(:, :)
    integer :: r
    allocate(t(3, this%n))
    do r = 1, this%n
      t(:, r) = [int(this%first(r), i8), this%gid(r), int(this%first(r + 1) - this%first(r), i8)]
    end do
  end function number_runs_table

  !> Global numbers of all items (ascending).
  pure function number_runs_numbers(this) result(g)
    class(number_runs_t), intent(in) :: this
    integer(i8), allocatable :: g(:)
    integer :: r, k
    allocate(g(this%n_items))
    do r = 1, this%n
      do k = this%first(r), this%first(r + 1) - 1
        g(k) = this%gid(r) + (k - this%first(r))
      end do
    end do
  end function number_runs_numbers

  !> The item numbered g (0 when none is).
  pure integer function number_runs_item_of(this, g) result(k)
    class(number_runs_t), intent(in) :: this
    integer(i8), intent(in) :: g
    integer :: lo, hi, mid
    k = 0
    if (this%n == 0) return
    if (g < this%gid(1)) return
    ! the last run numbered from at most g
    lo = 1
    hi = this%n
    do while (lo < hi)
      mid = (lo + hi + 1)/2
      if (this%gid(mid) <= g) then
        lo = mid
      else
        hi = mid - 1
      end if
    end do
    if (g - this%gid(lo) < this%first(lo + 1) - this%first(lo)) &
      k = this%first(lo) + int(g - this%gid(lo))
  end function number_runs_item_of

  !> No runs.
  pure subroutine number_runs_free(this)
    class(number_runs_t), intent(inout) :: this
    if (allocated(this%first)) deallocate(this%first)
    if (allocated(this%gid)) deallocate(this%gid)
    this%n = 0
    this%n_items = 0
    this%scale = 0.0_wp
  end subroutine number_runs_free

  !> The position of the last element of the ascending list a that is at most x (a(1) <= x).
  pure integer function last_at_or_below(a, x) result(lo)
    integer, intent(in) :: a(:), x
    integer :: hi, mid
    lo = 1
    hi = size(a)
    do while (lo < hi)
      mid = (lo + hi + 1)/2
      if (a(mid) <= x) then
        lo = mid
      else
        hi = mid - 1
      end if
    end do
  end function last_at_or_below
end module iem_number_runs
