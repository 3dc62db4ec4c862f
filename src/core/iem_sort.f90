!> In-place sorting of 64-bit integer keys (heap sort: O(n log n), no extra memory).
module iem_sort
  use iem_kinds, only: i8
  implicit none
  private
  public :: sort_i8

contains

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
end module iem_sort
