!> Time functions scaling loads and prescribed velocities: constant, step, linear ramp. The
!> input's spec (its kind a word) becomes a time_function_t once, at the model's set-up, whose
!> kind is a code: the time loop evaluates them with no string handling.
module iem_time_function
  use iem_kinds, only: wp
  use iem_config, only: time_function_spec_t
  implicit none
  private
  public :: time_function_t, time_function, tf_value, tf_rate
  public :: tf_constant, tf_step, tf_ramp

  !> The kinds' codes.
  integer, parameter :: tf_constant = 0, tf_step = 1, tf_ramp = 2

  !> A time function: its kind's code, its start and its ramp's duration (ramp only).
  type :: time_function_t
    integer :: kind = tf_constant
    real(wp) :: t_start = 0.0_wp
    real(wp) :: t_ramp = 0.0_wp
  end type time_function_t

contains

  !> The time function of the input's spec ('step', 'ramp'; any other kind: constant, as the
  !> input's checks leave only those three).
  pure function time_function(spec) result(tf)
    type(time_function_spec_t), intent(in) :: spec
    type(time_function_t) :: tf
    select case (trim(spec%kind))
    case ('step')
      tf%kind = tf_step
    case ('ramp')
      tf%kind = tf_ramp
    case default
      tf%kind = tf_constant
    end select
    tf%t_start = spec%t_start
    tf%t_ramp = spec%t_ramp
  end function time_function

  !> Value of the time function at time t (0 before the start of a step or ramp).
  pure real(wp) function tf_value(tf, t) result(f)
    type(time_function_t), intent(in) :: tf
    real(wp), intent(in) :: t
    select case (tf%kind)
    case (tf_step)
      f = merge(1.0_wp, 0.0_wp, t >= tf%t_start)
    case (tf_ramp)
      f = min(max((t - tf%t_start)/tf%t_ramp, 0.0_wp), 1.0_wp)
    case default
      f = 1.0_wp
    end select
  end function tf_value

  !> Time derivative of the time function at t (the step's jump is not represented).
  pure real(wp) function tf_rate(tf, t) result(r)
    type(time_function_t), intent(in) :: tf
    real(wp), intent(in) :: t
    r = 0.0_wp
    if (tf%kind == tf_ramp) then
      if (t >= tf%t_start .and. t < tf%t_start + tf%t_ramp) r = 1.0_wp/tf%t_ramp
    end if
  end function tf_rate
end module iem_time_function
