!> Time functions scaling loads and prescribed velocities: constant, step, linear ramp.
module iem_time_function
  use iem_kinds, only: wp
  use iem_config, only: time_function_spec_t
  implicit none
  private
  public :: tf_value, tf_rate

contains

  !> Value of the time function at time t (0 before the start of a step or ramp).
  pure real(wp) function tf_value(tf, t) result(f)
    type(time_function_spec_t), intent(in) :: tf
    real(wp), intent(in) :: t
    select case (trim(tf%kind))
    case ('step')
      f = merge(1.0_wp, 0.0_wp, t >= tf%t_start)
    case ('ramp')
      f = min(max((t - tf%t_start)/tf%t_ramp, 0.0_wp), 1.0_wp)
    case default
      f = 1.0_wp
    end select
  end function tf_value

  !> Time derivative of the time function at t (the step's jump is not represented).
  pure real(wp) function tf_rate(tf, t) result(r)
    type(time_function_spec_t), intent(in) :: tf
    real(wp), intent(in) :: t
    r = 0.0_wp
    if (trim(tf%kind) == 'ramp') then
      if (t >= tf%t_start .and. t < tf%t_start + tf%t_ramp) r = 1.0_wp/tf%t_ramp
    end if
  end function tf_rate
end module iem_time_function
