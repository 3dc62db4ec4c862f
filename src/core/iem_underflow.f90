!> The floating-point underflow mode of a run: while the solver's loop goes, results below
!> the smallest normal double (2.2e-308 in magnitude) are flushed to zero instead of kept as
!> subnormals, which many processors compute tens of times slower (docs/numerics.md,
!> "Subnormal numbers"). The caller's mode is put back afterwards.
module iem_underflow
  use, intrinsic :: ieee_arithmetic, only: ieee_support_underflow_control, &
                                           ieee_get_underflow_mode, ieee_set_underflow_mode
  use iem_kinds, only: wp
  implicit none
  private
  public :: flush_subnormals, restore_underflow

contains

  !> Flush subnormal results to zero from now on, where the processor can; gradual returns
  !> the mode found (for restore_underflow).
  subroutine flush_subnormals(gradual)
    logical, intent(out) :: gradual
    gradual = .true.
    if (.not. ieee_support_underflow_control(1.0_wp)) return
    call ieee_get_underflow_mode(gradual)
    call ieee_set_underflow_mode(.false.)
  end subroutine flush_subnormals

  !> Put back the underflow mode that flush_subnormals found.
  subroutine restore_underflow(gradual)
    logical, intent(in) :: gradual
    if (ieee_support_underflow_control(1.0_wp)) call ieee_set_underflow_mode(gradual)
  end subroutine restore_underflow
end module iem_underflow
