!> Sorting: 64-bit integer keys in place (heap sort: O(n log n), no extra memory), and the
!> stable ordering of n items by an integer key (merge sort: O(n log n)); real keys through
!> real_key. (Keys, not a caller's comparison: an internal procedure passed as the
!> comparison needs a trampoline on an executable stack.)
module iem_sort
  use iem_kinds, only: i8, wp
  implicit none
  private
  public :: sort_i8, stable_sort_by, real_key, sum_by_label, order_by_node

contains

  !> The distinct labels of pairs = (label, value, label, value, ...), ascending, in keys,
  !> and the sum of the values of each label, in sums.
  pure subroutine sum_by_label(pairs, keys, sums)
    integer(i8), intent(in) :: pairs(:)
    integer(i8), allocatable, intent(out) :: keys(:), sums(:)
    integer :: n, m, k, a, b, mid
    n = size(pairs)/2
    keys = pairs(1:2*n:2)
    call sort_i8(keys)
    m = 0
    do k = 1, n
      if (m > 0) then
        if (keys(k) == keys(m)) cycle
      end if
      m = m + 1
      keys(m) = keys(k)
    end do
    keys = keys(1:m)
    allocate(sums(m), source=0_i8)
    do k = 1, n
      a = 1
      b = m
      do while (a < b)
        mid = (a + b)/2
        if (keys(mid) < pairs(2*k - 1)) then
          a = mid + 1
        else
          b = mid
        end if
      end do
      sums(a) = sums(a) + pairs(2*k)
    end do
  end subroutine sum_by_label

  !> Reorder the item indices order(:) by key(order(:)) ascending, items with equal keys
  !> keeping their order (a bottom-up merge sort); sorting by the last criterion first, then
  !> by each one before it, orders by all of them.
  pure subroutine stable_sort_by(key, order)
    integer(i8), intent(in) :: key(:)
    integer, intent(inout) :: order(:)
    integer, allocatable :: tmp(:)
    integer :: n, width, lo, mid, hi, i, j, k
    logical :: take_left
    n = size(order)
    allocate(tmp(n))
    width = 1
    do while (width < n)
      do lo = 1, n, 2*width
        mid = min(lo + width, n + 1)
        hi = min(lo + 2*width, n + 1)
        i = lo
        j = mid
        do k = lo, hi - 1
          take_left = i < mid
          if (take_left .and. j < hi) take_left = key(order(j)) >= key(order(i))
          if (take_left) then
            tmp(k) = order(i)
            i = i + 1
          else
            tmp(k) = order(j)
            j = j + 1
          end if
        end do
      end do
      order = tmp
      width = 2*width
    end do
  end subroutine stable_sort_by

  !> An integer key in the order of the real x (not NaN): a < b exactly when
  !> real_key(a) < real_key(b), and -0 and +0 give the same key (where the run flushes
  !> subnormals, a subnormal x keys as 0, as comparisons of x then order it).
  elemental integer(i8) function real_key(x)
    real(wp), intent(in) :: x
    real(wp) :: z
    ! -0 + 0 is +0; a negative value's bits, all but the sign flipped, order as its value
    z = x + 0.0_wp
    real_key = transfer(z, 0_i8)
    if (real_key < 0_i8) real_key = ieor(real_key, huge(0_i8))
  end function real_key

  !> Sort a(:) ascending.
  pure subroutine sort_i8(a)
    integer(i8), intent(inout) :: a(:)
    integer :: n, k
    integer(i8) :: t
    n = size(a)
    do k = n/2, 1, -1
      call sift_down(a, k, n)
    end do
    do k = n, 2, -1
      t = a(1)
      a(1) = a(k)
      a(k) = t
      call sift_down(a, 1, k - 1)
    end do
  end subroutine sort_i8

  pure subroutine sift_down(a, start, last)
    integer(i8), intent(inout) :: a(:)
    integer, intent(in) :: start, last
    integer :: root, child
    integer(i8) :: t
    root = start
    do
      child = 2*root
      if (child > last) exit
      if (child < last) then
        if (a(child + 1) > a(child)) child = child + 1
      end if
      if (a(root) >= a(child)) exit
      t = a(root)
      a(root) = a(child)
      a(child) = t
      root = child
    end do
  end subroutine sift_down

  !> The entries of node (values 1..n_nodes) in ascending order of their nodes, entries of
  !> one node in their order.
  pure subroutine order_by_node(node, n_nodes, order)
    integer, intent(in) :: node(:), n_nodes
    integer, allocatable, intent(out) :: order(:)
    integer, allocatable :: first(:)
    integer :: j, l
    ! a counting sort: first(l) is where node l's entries start
    allocate(first(n_nodes + 1), order(size(node)))
    first = 0
    do j = 1, size(node)
      first(node(j)) = first(node(j)) + 1
    end do
    l = 1
    do j = 1, n_nodes + 1
      l = l + first(j)
      first(j) = l - first(j)
    end do
    do j = 1, size(node)
      order(first(node(j))) = j
      first(node(j)) = first(node(j)) + 1
    end do
  end subroutine order_by_node
end module iem_sort
