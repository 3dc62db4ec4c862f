!> RK4's passes over the owned nodes for states of 6 values a node (u, v, w: capped stiffness
!> damping's filtered velocity w, docs/model.md), as iem_node_pass's are for 4: the stage's
!> rates k = (v, a, r), a = -(f + alpha m v)/m from the summed forces f (cleared for the next
!> evaluation) and the filter's rate r = omega_cap (v - w), and the stage's update in the same
!> pass, so that no stage writes or reads the rates as an array; and the same update from
!> rates formed before it (rk4_finish_step's passes one after the other). They run in
!> iem_node_pass_filtered.c, where every value is formed by the same operations either way
!> (a = -fma(alpha m, v, f)/m, y + w k = fma(w, k, y)), so the two are bit for bit the same
!> (test_iem_integrator). The rates of the prescribed dofs are not imposed in the fused
!> passes: their velocities are set again before every stage and at the step's end.
module iem_node_pass_filtered
  use, intrinsic :: iso_c_binding, only: c_int, c_double
  implicit none
  private
  public :: rk4_filtered_first, rk4_filtered_mid, rk4_filtered_last, rk4_filtered_update
  public :: rk4_filtered_last_update

  interface
    !> Stage 1 at the state y(6, n): ynew = y + wdt k1 and the next stage state
    !> ys = y + h k1, clearing f(2, n).
    pure subroutine rk4_filtered_first(n, alpha, omega_cap, mass, wdt, h, y, f, ynew, ys) &
        bind(c, name='iem_rk4_filtered_first')
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), value :: alpha, omega_cap, wdt, h
      real(c_double), intent(in) :: mass(*), y(*)
      real(c_double), intent(inout) :: f(*), ynew(*), ys(*)
    end subroutine rk4_filtered_first
    !> Stage 2 or 3 at the stage state ys: ynew = ynew + wdt k_s, and ys becomes the next
    !> stage state y0 + h k_s (y0: the state at the start of the step), clearing f.
    pure subroutine rk4_filtered_mid(n, alpha, omega_cap, mass, wdt, h, y0, f, ynew, ys) &
        bind(c, name='iem_rk4_filtered_mid')
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), value :: alpha, omega_cap, wdt, h
      real(c_double), intent(in) :: mass(*), y0(*)
      real(c_double), intent(inout) :: f(*), ynew(*), ys(*)
    end subroutine rk4_filtered_mid
    !> Stage 4 at the stage state ys: ynew = ynew + wdt k4, clearing f, with the sum of the
    !> new values in total (which only says whether they are all finite).
    pure subroutine rk4_filtered_last(n, alpha, omega_cap, mass, wdt, ys, f, ynew, total) &
        bind(c, name='iem_rk4_filtered_last')
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), value :: alpha, omega_cap, wdt
      real(c_double), intent(in) :: mass(*), ys(*)
      real(c_double), intent(inout) :: f(*), ynew(*)
      real(c_double), intent(out) :: total
    end subroutine rk4_filtered_last
    !> A stage's update but the last from its rates formed before (velocities yk(3:4, n),
    !> rates acc(4, n): accelerations and the filter's): ynew = (first /= 0: y, else ynew)
    !> + wdt k and ys = y + h k (ys may be yk).
    subroutine rk4_filtered_update(n, first, wdt, h, y, yk, acc, ynew, ys) &
        bind(c, name='iem_rk4_filtered_update')
      import :: c_int, c_double
      integer(c_int), value :: n, first
      real(c_double), value :: wdt, h
      real(c_double), intent(in) :: y(*), yk(*), acc(*)
      real(c_double), intent(inout) :: ynew(*), ys(*)
    end subroutine rk4_filtered_update
    !> The last stage's update from its rates formed before: ynew = ynew + wdt k, with the
    !> sum of the new values in total (which only says whether they are all finite).
    pure subroutine rk4_filtered_last_update(n, wdt, ys, acc, ynew, total) &
        bind(c, name='iem_rk4_filtered_last_update')
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), value :: wdt
      real(c_double), intent(in) :: ys(*), acc(*)
      real(c_double), intent(inout) :: ynew(*)
      real(c_double), intent(out) :: total
    end subroutine rk4_filtered_last_update
  end interface
end module iem_node_pass_filtered
