!> Cache prefetch hints (iem_prefetch_c.c): the force kernel asks for the next chunk's node
!> rows while it works on the current one, so their loads do not wait on memory. A hint
!> changes no value.
module iem_prefetch
  use, intrinsic :: iso_c_binding, only: c_double, c_int
  implicit none
  private
  public :: prefetch

  interface
    !> Bring the n values from a into the caches (write /= 0: for writing); values unchanged,
    !> so declared pure.
    pure subroutine prefetch(a, n, write) bind(C, name='iem_cache_prefetch')
      import :: c_double, c_int
      real(c_double), intent(in) :: a(*)
      integer(c_int), value :: n, write
    end subroutine prefetch
  end interface
end module iem_prefetch
