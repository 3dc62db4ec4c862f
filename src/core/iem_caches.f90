!> The processor's cache sizes (iem_caches.c), for work sized to stay in a cache: RK4's
!> wavefront sizes its bands by the second-level cache (iem_stage_wave).
module iem_caches
  use iso_c_binding, only: c_long
  use iem_kinds, only: i8
  implicit none
  private
  public :: l2_bytes

  interface
    !> Bytes of a core's second-level cache as the C library reports them (0: not known).
    function c_l2_bytes() result(n) bind(C, name='iem_l2_bytes')
      import :: c_long
      integer(c_long) :: n
    end function c_l2_bytes
  end interface

contains

  !> Bytes of a core's second-level cache (0 where the system does not say).
  integer(i8) function l2_bytes()
    l2_bytes = int(c_l2_bytes(), i8)
  end function l2_bytes
end module iem_caches
