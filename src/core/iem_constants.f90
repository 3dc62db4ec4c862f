!> Mathematical constants and small numerical thresholds shared by all modules.
module iem_constants
  use iem_kinds, only: wp
  implicit none
  private
  public :: pi, half_pi, rk4_imag_limit, unset_real, unset_int

  !> pi to working precision.
  real(wp), parameter :: pi = 3.141592653589793238462643383279502884_wp
  !> pi / 2: a cell corner's undeformed angle.
  real(wp), parameter :: half_pi = 0.5_wp*pi
  !> RK4 is stable for undamped oscillation while dt*omega <= 2*sqrt(2).
  real(wp), parameter :: rk4_imag_limit = 2.828427124746190097603377448419396157_wp
  !> Marker for a real input that the user did not give.
  real(wp), parameter :: unset_real = -huge(1.0_wp)
  !> Marker for an integer input that the user did not give.
  integer, parameter :: unset_int = -huge(1)
end module iem_constants
