!> The pass over a rank's owned nodes that follows the cell forces: the accelerations
!> a = -(f + alpha m v)/m from the summed forces f (external loads already folded in as -f_ext),
!> clearing f for the next evaluation, and for RK4 the stage's update fused into the same
!> pass, so that no stage reads or writes the rates as a separate array (docs/architecture.md,
!> "The node passes"; 6 values a node: iem_node_pass_filtered). The classical scheme:
!> k_s = (v_s, a_s), y_new = y + dt sum w_s k_s, stage states y + h_s k_s, each value with
!> the same arithmetic as separate passes would do.
!> Where iem_node_pass_simd.c is built with AVX2 and FMA, the RK4 passes and Verlet's fused
!> kicks on states of 4 values a node run there, a node a vector, bit for bit as the loops
!> here (which run otherwise).
module iem_node_pass
  use, intrinsic :: iso_c_binding, only: c_int, c_double
  use iem_kinds, only: wp
  implicit none
  private
  public :: rk4_stage_t, accelerations, guarded_kick, rk4_first_pass, rk4_mid_pass, rk4_last_pass
  public :: kick_drift, accelerations_in_place, node_pass_simd, use_simd, mass_damping_powers

  !> Whether the passes built in iem_node_pass_simd.c are used when built (tests clear it to
  !> compare them with the loops here).
  logical :: use_simd = .true.

  interface
    !> 1 when iem_node_pass_simd.c's passes are built (AVX2 and FMA), else 0.
    pure integer(c_int) function c_simd() bind(c, name='iem_node_pass_simd')
      import :: c_int
    end function c_simd
    !> rk4_first_pass, where built.
    pure subroutine c_first(n, alpha, mass, wdt, h, y, f, ynew, ys) &
        bind(c, name='iem_rk4_first_pass')
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), value :: alpha, wdt, h
      real(c_double), intent(in) :: mass(*), y(*)
      real(c_double), intent(inout) :: f(*), ynew(*), ys(*)
    end subroutine c_first
    !> rk4_mid_pass, where built.
    pure subroutine c_mid(n, alpha, mass, wdt, h, y0, f, ynew, ys) &
        bind(c, name='iem_rk4_mid_pass')
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), value :: alpha, wdt, h
      real(c_double), intent(in) :: mass(*), y0(*)
      real(c_double), intent(inout) :: f(*), ynew(*), ys(*)
    end subroutine c_mid
    !> rk4_last_pass, where built.
    pure subroutine c_last(n, alpha, mass, wdt, ys, f, ynew, total) &
        bind(c, name='iem_rk4_last_pass')
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), value :: alpha, wdt
      real(c_double), intent(in) :: mass(*), ys(*)
      real(c_double), intent(inout) :: f(*), ynew(*)
      real(c_double), intent(out) :: total
    end subroutine c_last
    !> accelerations_in_place with kick, where built.
    pure subroutine c_kick(n, alpha, mass, h, y, fa, first_bad) &
        bind(c, name='iem_kick_in_place')
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), value :: alpha, h
      real(c_double), intent(in) :: mass(*)
      real(c_double), intent(inout) :: y(*), fa(*)
      integer(c_int), intent(out) :: first_bad
    end subroutine c_kick
    !> accelerations_in_place with kick and drift, where built.
    pure subroutine c_kick_ahead(n, alpha, mass, h, dt, y, fa, first_bad) &
        bind(c, name='iem_kick_ahead')
      import :: c_int, c_double
      integer(c_int), value :: n
      real(c_double), value :: alpha, h, dt
      real(c_double), intent(in) :: mass(*)
      real(c_double), intent(inout) :: y(*), fa(*)
      integer(c_int), intent(out) :: first_bad
    end subroutine c_kick_ahead
    !> kick_drift, where built.
    pure subroutine c_kick_drift(n, h, dt, acc, y, clear) &
        bind(c, name='iem_kick_drift')
      import :: c_int, c_double
      integer(c_int), value :: n, clear
      real(c_double), value :: h, dt
      real(c_double), intent(inout) :: acc(*), y(*)
    end subroutine c_kick_drift
  end interface

  !> An RK4 stage for the node pass: its number (1..4), w_s dt, the offset h of the next
  !> stage state, and after the last stage the sum of the new state's owned values (not
  !> finite when any value is not).
  type :: rk4_stage_t
    integer :: stage = 0
    real(wp) :: wdt = 0.0_wp, h = 0.0_wp, total = 0.0_wp
  end type rk4_stage_t

contains

  !> Whether the passes of iem_node_pass_simd.c run (built with AVX2 and FMA, and use_simd).
  pure logical function node_pass_simd()
    node_pass_simd = use_simd .and. c_simd() == 1
  end function node_pass_simd

  !> Accelerations acc(1:2, l) = -(f + alpha m v)/m of the owned nodes 1..n (velocities in
  !> y(3:4, :)), clearing f(:, 1:n); with kick, then the velocities' half kick v += kick a
  !> (velocity Verlet's second kick, fused), guarded: at a node whose new velocities are not
  !> both finite, acc(1:2) keeps the velocities before the kick instead of the accelerations
  !> (so that they can be given back, iem_verlet's rejected); first_bad is the first such node
  !> (0: none). Branch-free, so that the loop vectorises.
  pure subroutine accelerations(n, alpha, mass, y, f, acc, kick, first_bad)
    integer, intent(in) :: n
    real(wp), intent(in) :: alpha, mass(:)
    real(wp), intent(inout), contiguous :: y(:, :)
    real(wp), intent(inout), contiguous :: f(:, :), acc(:, :)
    real(wp), intent(in), optional :: kick
    integer, intent(out), optional :: first_bad
    real(wp) :: h, a1, a2
    integer :: l, first
    logical :: ok
    if (present(kick)) then
      h = kick
      first = n + 1
      do l = 1, n
        a1 = -(f(1, l) + alpha*mass(l)*y(3, l))/mass(l)
        a2 = -(f(2, l) + alpha*mass(l)*y(4, l))/mass(l)
        f(1, l) = 0.0_wp
        f(2, l) = 0.0_wp
        call kick_node(h, a1, a2, y(3, l), y(4, l), acc(1, l), acc(2, l), ok)
        first = min(first, merge(n + 1, l, ok))
      end do
      if (present(first_bad)) first_bad = merge(first, 0, first <= n)
      return
    end if
    if (present(first_bad)) first_bad = 0
    do l = 1, n
      acc(1, l) = -(f(1, l) + alpha*mass(l)*y(3, l))/mass(l)
      acc(2, l) = -(f(2, l) + alpha*mass(l)*y(4, l))/mass(l)
      f(1, l) = 0.0_wp
      f(2, l) = 0.0_wp
    end do
  end subroutine accelerations

  !> As accelerations, the accelerations written over the forces they come from:
  !> fa(1:2, l) = -(fa + alpha m v)/m of the owned nodes 1..n (velocity Verlet with its forces
  !> summed into its rates array); with kick, then v += kick a, guarded as in accelerations
  !> (fa keeps the velocities before the kick where the new ones are not both finite). With
  !> kick and drift (4 values a node), at each node whose kicked velocities are both finite
  !> the next step's first kick and drift follow in the same pass, v += kick a, u += drift v,
  !> bit for bit kick_drift's, and fa is cleared there (for the next step's forces).
  pure subroutine accelerations_in_place(n, alpha, mass, y, fa, kick, first_bad, drift)
    integer, intent(in) :: n
    real(wp), intent(in), contiguous :: mass(:)
    real(wp), intent(in) :: alpha
    real(wp), intent(inout), contiguous :: y(:, :), fa(:, :)
    real(wp), intent(in), optional :: kick
    integer, intent(out), optional :: first_bad
    real(wp), intent(in), optional :: drift
    real(wp) :: a1, a2
    integer :: l, first
    integer(c_int) :: bad
    logical :: ok
    if (present(drift) .and. size(y, 1) /= 4) error stop 'accelerations_in_place: drift, 4 values'
    if (present(kick) .and. node_pass_simd() .and. size(y, 1) == 4 .and. size(fa, 1) == 2) then
      if (present(drift)) then
        call c_kick_ahead(n, alpha, mass, kick, drift, y, fa, bad)
      else
        call c_kick(n, alpha, mass, kick, y, fa, bad)
      end if
      if (present(first_bad)) first_bad = bad
      return
    end if
    if (.not. present(kick)) then
      do l = 1, n
        fa(1, l) = -(fa(1, l) + alpha*mass(l)*y(3, l))/mass(l)
        fa(2, l) = -(fa(2, l) + alpha*mass(l)*y(4, l))/mass(l)
      end do
      if (present(first_bad)) first_bad = 0
      return
    end if
    first = n + 1
    do l = 1, n
      a1 = -(fa(1, l) + alpha*mass(l)*y(3, l))/mass(l)
      a2 = -(fa(2, l) + alpha*mass(l)*y(4, l))/mass(l)
      call kick_node(kick, a1, a2, y(3, l), y(4, l), fa(1, l), fa(2, l), ok)
      first = min(first, merge(n + 1, l, ok))
    end do
    if (present(first_bad)) first_bad = merge(first, 0, first <= n)
    if (present(drift)) call drift_ahead(n, kick, drift, y, fa)
  end subroutine accelerations_in_place

  !> The next step's kick v += h a and drift u += dt v (kick_drift's loop) of the owned nodes
  !> 1..n whose velocities (just kicked) are both finite, clearing fa there: the rest of
  !> accelerations_in_place's pass with drift where the C pass is not built. (In the kick's
  !> loop gfortran, tuned for this processor, left the second multiply-add of a velocity
  !> uncontracted, a chain of two, and so rounded it otherwise than kick_drift.)
  pure subroutine drift_ahead(n, h, dt, y, fa)
    integer, intent(in) :: n
    real(wp), intent(in) :: h, dt
    real(wp), intent(inout), contiguous :: y(:, :), fa(:, :)
    integer :: l
    do l = 1, n
      if (.not. (y(3, l) - y(3, l)) + (y(4, l) - y(4, l)) == 0.0_wp) cycle
      y(3, l) = y(3, l) + h*fa(1, l)
      y(4, l) = y(4, l) + h*fa(2, l)
      y(1, l) = y(1, l) + dt*y(3, l)
      y(2, l) = y(2, l) + dt*y(4, l)
      fa(1, l) = 0.0_wp
      fa(2, l) = 0.0_wp
    end do
  end subroutine drift_ahead

  !> Velocity Verlet's second kick v += h a of the owned nodes 1..n (accelerations acc(1:2, :),
  !> velocities y(3:4, :)), guarded as the fused pass of accelerations: at a node whose new
  !> velocities are not both finite acc(1:2) keeps the velocities before the kick; first_bad
  !> is the first such node (0: none).
  pure subroutine guarded_kick(n, h, acc, y, first_bad)
    integer, intent(in) :: n
    real(wp), intent(in) :: h
    real(wp), intent(inout), contiguous :: acc(:, :), y(:, :)
    integer, intent(out) :: first_bad
    real(wp) :: a1, a2
    integer :: l, first
    logical :: ok
    first = n + 1
    do l = 1, n
      a1 = acc(1, l)
      a2 = acc(2, l)
      call kick_node(h, a1, a2, y(3, l), y(4, l), acc(1, l), acc(2, l), ok)
      first = min(first, merge(n + 1, l, ok))
    end do
    first_bad = merge(first, 0, first <= n)
  end subroutine guarded_kick

  !> One node's guarded half kick (the kicks above): the velocities v1, v2 become v + h a;
  !> ok when both new ones are finite, and then r1, r2 = a1, a2, else the velocities before
  !> the kick (for the rejected step). Branch-free, so that the loops that call it vectorise.
  pure subroutine kick_node(h, a1, a2, v1, v2, r1, r2, ok)
    real(wp), intent(in) :: h, a1, a2
    real(wp), intent(inout) :: v1, v2
    real(wp), intent(out) :: r1, r2
    logical, intent(out) :: ok
    real(wp) :: w1, w2
    w1 = v1
    w2 = v2
    v1 = w1 + h*a1
    v2 = w2 + h*a2
    ! x - x is 0 for a finite x, NaN for an infinite or NaN one: one test for both
    ok = (v1 - v1) + (v2 - v2) == 0.0_wp
    r1 = merge(a1, w1, ok)
    r2 = merge(a2, w2, ok)
  end subroutine kick_node

  !> Velocity Verlet's first kick and drift of the owned nodes 1..n in one pass:
  !> v += h acc, then u += dt v (prescribed velocities are the caller's to mend); with clear,
  !> acc(1:2, 1:n) is zeroed after it is read (the rates array then sums the next forces).
  pure subroutine kick_drift(n, h, dt, acc, y, clear)
    integer, intent(in) :: n
    real(wp), intent(in) :: h, dt
    real(wp), intent(inout), contiguous :: acc(:, :)
    real(wp), intent(inout), contiguous :: y(:, :)
    logical, intent(in), optional :: clear
    integer :: l
    logical :: zero
    zero = .false.
    if (present(clear)) zero = clear
    if (node_pass_simd() .and. size(y, 1) == 4 .and. size(acc, 1) == 2) then
      call c_kick_drift(n, h, dt, acc, y, merge(1_c_int, 0_c_int, zero))
      return
    end if
    if (zero) then
      do l = 1, n
        y(3, l) = y(3, l) + h*acc(1, l)
        y(4, l) = y(4, l) + h*acc(2, l)
        y(1, l) = y(1, l) + dt*y(3, l)
        y(2, l) = y(2, l) + dt*y(4, l)
        acc(1, l) = 0.0_wp
        acc(2, l) = 0.0_wp
      end do
      return
    end if
    do l = 1, n
      y(3, l) = y(3, l) + h*acc(1, l)
      y(4, l) = y(4, l) + h*acc(2, l)
      y(1, l) = y(1, l) + dt*y(3, l)
      y(2, l) = y(2, l) + dt*y(4, l)
    end do
  end subroutine kick_drift

  !> Stage 1 at the state y (u, v): ynew = y + wdt k1 and the next stage state
  !> ys = y + h k1, clearing f; (u, v) only (4 values a node).
  pure subroutine rk4_first_pass(n, alpha, mass, wdt, h, y, f, ynew, ys)
    integer, intent(in) :: n
    real(wp), intent(in) :: alpha, wdt, h
    real(wp), intent(in), contiguous :: mass(:), y(:, :)
    real(wp), intent(inout), contiguous :: f(:, :), ynew(:, :), ys(:, :)
    real(wp) :: a1, a2, v1, v2
    integer :: l
    if (node_pass_simd() .and. size(y, 1) == 4 .and. size(f, 1) == 2) then
      call c_first(n, alpha, mass, wdt, h, y, f, ynew, ys)
      return
    end if
    do l = 1, n
      v1 = y(3, l)
      v2 = y(4, l)
      a1 = -(f(1, l) + alpha*mass(l)*v1)/mass(l)
      a2 = -(f(2, l) + alpha*mass(l)*v2)/mass(l)
      f(1, l) = 0.0_wp
      f(2, l) = 0.0_wp
      ynew(1, l) = y(1, l) + wdt*v1
      ynew(2, l) = y(2, l) + wdt*v2
      ynew(3, l) = y(3, l) + wdt*a1
      ynew(4, l) = y(4, l) + wdt*a2
      ys(1, l) = y(1, l) + h*v1
      ys(2, l) = y(2, l) + h*v2
      ys(3, l) = y(3, l) + h*a1
      ys(4, l) = y(4, l) + h*a2
    end do
  end subroutine rk4_first_pass

  !> Stage 2 or 3 at the stage state ys: ynew = ynew + wdt k_s, and ys becomes the next
  !> stage state y0 + h k_s (y0: the state at the start of the step), clearing f.
  pure subroutine rk4_mid_pass(n, alpha, mass, wdt, h, y0, f, ynew, ys)
    integer, intent(in) :: n
    real(wp), intent(in) :: alpha, wdt, h
    real(wp), intent(in), contiguous :: mass(:), y0(:, :)
    real(wp), intent(inout), contiguous :: f(:, :), ynew(:, :), ys(:, :)
    real(wp) :: a1, a2, v1, v2
    integer :: l
    if (node_pass_simd() .and. size(ys, 1) == 4 .and. size(f, 1) == 2) then
      call c_mid(n, alpha, mass, wdt, h, y0, f, ynew, ys)
      return
    end if
    do l = 1, n
      v1 = ys(3, l)
      v2 = ys(4, l)
      a1 = -(f(1, l) + alpha*mass(l)*v1)/mass(l)
      a2 = -(f(2, l) + alpha*mass(l)*v2)/mass(l)
      f(1, l) = 0.0_wp
      f(2, l) = 0.0_wp
      ynew(1, l) = ynew(1, l) + wdt*v1
      ynew(2, l) = ynew(2, l) + wdt*v2
      ynew(3, l) = ynew(3, l) + wdt*a1
      ynew(4, l) = ynew(4, l) + wdt*a2
      ys(1, l) = y0(1, l) + h*v1
      ys(2, l) = y0(2, l) + h*v2
      ys(3, l) = y0(3, l) + h*a1
      ys(4, l) = y0(4, l) + h*a2
    end do
  end subroutine rk4_mid_pass

  !> Stage 4 at the stage state ys: ynew = ynew + wdt k4, clearing f, with the sum of the
  !> new values in total (eight partial sums, so that the loop vectorises).
  pure subroutine rk4_last_pass(n, alpha, mass, wdt, ys, f, ynew, total)
    integer, intent(in) :: n
    real(wp), intent(in) :: alpha, wdt
    real(wp), intent(in), contiguous :: mass(:), ys(:, :)
    real(wp), intent(inout), contiguous :: f(:, :), ynew(:, :)
    real(wp), intent(out) :: total
    real(wp) :: a1, a2, v1, v2, part(8)
    integer :: l, l0, j
    if (node_pass_simd() .and. size(ys, 1) == 4 .and. size(f, 1) == 2) then
      call c_last(n, alpha, mass, wdt, ys, f, ynew, total)
      return
    end if
    part = 0.0_wp
    do l0 = 0, n - 1, 8
      do j = 1, min(8, n - l0)
        l = l0 + j
        v1 = ys(3, l)
        v2 = ys(4, l)
        a1 = -(f(1, l) + alpha*mass(l)*v1)/mass(l)
        a2 = -(f(2, l) + alpha*mass(l)*v2)/mass(l)
        f(1, l) = 0.0_wp
        f(2, l) = 0.0_wp
        ynew(1, l) = ynew(1, l) + wdt*v1
        ynew(2, l) = ynew(2, l) + wdt*v2
        ynew(3, l) = ynew(3, l) + wdt*a1
        ynew(4, l) = ynew(4, l) + wdt*a2
        part(j) = part(j) + ((ynew(1, l) + ynew(2, l)) + (ynew(3, l) + ynew(4, l)))
      end do
    end do
    total = sum(part)
  end subroutine rk4_last_pass

  !> The mass damping's power alpha m |v|^2 of each of the nodes 1..n of the state y in pw,
  !> and their sum, in node order, added to p; with wd and w, each power times w added to
  !> the node's wd too (its work folded, model_t's wd_node). (Out of model_rate's internal
  !> procedure, whose host variables gfortran kept in memory: a store and a load a node.)
  pure subroutine mass_damping_powers(n, alpha, mass, y, pw, p, wd, w)
    integer, intent(in) :: n
    real(wp), intent(in) :: alpha, mass(:), y(:, :)
    real(wp), intent(inout) :: pw(:), p
    real(wp), intent(inout), optional :: wd(:)
    real(wp), intent(in), optional :: w
    real(wp) :: sum_p, pl
    integer :: l
    sum_p = p
    if (present(wd) .and. present(w)) then
      do l = 1, n
        pl = alpha*mass(l)*(y(3, l)**2 + y(4, l)**2)
        pw(l) = pl
        sum_p = sum_p + pl
        wd(l) = wd(l) + w*pl
      end do
    else
      do l = 1, n
        pw(l) = alpha*mass(l)*(y(3, l)**2 + y(4, l)**2)
        sum_p = sum_p + pw(l)
      end do
    end if
    p = sum_p
  end subroutine mass_damping_powers
end module iem_node_pass
