!> The cell laws of the force kernel, on a chunk of cells: the elastic law of the paper's
!> cell and of the bending-corrected cell (generalised stresses from edge strains and corner
!> shear measures, iem_spring_constants), the same cell by cell for several materials, and
!> the nonlinear (Masing) law of the paper's springs with its vectorisable fast path.
module iem_cell_laws
  use iem_kinds, only: wp, ip
  use iem_spring_constants, only: cell_constants_t, law_bending
  use iem_nonlinear_springs, only: nonlinear_springs_t, springs_per_cell, spring_kind, &
                                   spring_strains
  use iem_masing, only: masing_trial, masing_commit, masing_mirror_strain
  implicit none
  private
  public :: chunk, cell_law, cell_law_mixed, nonlinear_law

  !> Cells per chunk of the vectorised kernel: the chunk's work arrays stay in L1 cache.
  integer, parameter :: chunk = 64

contains
  !> The nonlinear law of the paper's cell on a chunk whose first cell is c_first: each
  !> spring's normalised stress psi from its committed history at its current strain (and,
  !> with accept, the history moved there), the generalised stresses g = 2 ce psi_edge +
  !> 2 ch (psi_Poisson at both ends of the edge), t = 2 cg psi_shear, and the work done on the
  !> cell's springs up to this state (trapezoidal increments from the committed state).
  pure subroutine nonlinear_law(nl, c_first, m, ep, s, accept, g, t, en, mat)
    type(nonlinear_springs_t), intent(inout) :: nl
    integer, intent(in) :: c_first, m
    real(wp), intent(in) :: ep(chunk, 4), s(chunk, 4)
    logical, intent(in) :: accept
    real(wp), intent(out) :: g(chunk, 4), t(chunk, 4), en(chunk)
    !> Material of each cell of the chunk (absent: material 1).
    integer, intent(in), optional :: mat(:)
    real(wp) :: e(springs_per_cell), psi(springs_per_cell), tan, dw, e_old, psi_old, er, x
    integer :: c, j, i, kind, mc
    logical :: fast
    mc = 1
    do c = 1, m
      if (present(mat)) mc = mat(c)
      e = spring_strains(ep(c, :), s(c, :))
      en(c) = 0.0_wp
      do j = 1, springs_per_cell
        i = springs_per_cell*(c_first + c - 2) + j
        kind = spring_kind(j)
        associate(st => nl%state)
          e_old = st%strain(i)
          psi_old = st%stress(i)
          fast = .true.
          if (e(j) == e_old) then
            psi(j) = psi_old
          else if (st%count(i) == 0 .and. (st%dir(i) == 0 .or. &
                   real(st%dir(i), wp)*(e(j) - e_old) > 0.0_wp)) then
            ! fast path: a spring on its skeleton that keeps going the same way
            er = merge(nl%er_pos(kind, mc), nl%er_neg(kind, mc), e(j) >= 0.0_wp)
            psi(j) = e(j)/(1.0_wp + abs(e(j))/er)
          else if (on_branch(st%count(i), st%dir(i), e(j), e_old, st%e_rev(:, i), &
                             nl%er_pos(kind, mc), nl%er_neg(kind, mc))) then
            ! fast path: a spring that keeps going the same way on its current Masing branch,
            ! short of the point where that branch ends (as masing_trial would find)
            associate(n => st%count(i))
              x = 0.5_wp*(e(j) - st%e_rev(n, i))
              psi(j) = st%s_rev(n, i) + 2.0_wp*(x/(1.0_wp + abs(x)/ &
                       (0.5_wp*(nl%er_pos(kind, mc) + nl%er_neg(kind, mc)))))
            end associate
          else
            fast = .false.
          end if
          if (accept) then
            if (fast) then
              ! no reversal and no branch ends: the commit moves along the same curve (what
              ! masing_commit does in this case, bit for bit)
              if (e(j) /= e_old) then
                st%dir(i) = merge(1_ip, -1_ip, e(j) > e_old)
                st%strain(i) = e(j)
                st%stress(i) = psi(j)
                st%e_max_pos(i) = max(st%e_max_pos(i), e(j))
                st%e_max_neg(i) = min(st%e_max_neg(i), e(j))
              end if
            else
              call masing_commit(e(j), 1.0_wp, nl%er_pos(kind, mc), nl%er_neg(kind, mc), &
                                 st%strain(i), st%stress(i), st%dir(i), st%count(i), &
                                 st%e_rev(:, i), st%s_rev(:, i), st%e_max_pos(i), &
                                 st%e_max_neg(i))
              ! the committed stress is bit for bit the trial stress at the same strain
              psi(j) = st%stress(i)
            end if
          else if (.not. fast) then
            call masing_trial(e(j), 1.0_wp, nl%er_pos(kind, mc), nl%er_neg(kind, mc), &
                              st%strain(i), st%stress(i), st%dir(i), st%count(i), st%e_rev(:, i), &
                              st%s_rev(:, i), psi(j), tan)
          end if
          dw = 0.5_wp*nl%c2(kind, mc)*(psi_old + psi(j))*(e(j) - e_old)
          if (accept) then
            nl%work(i) = nl%work(i) + dw
            en(c) = en(c) + nl%work(i)
          else
            en(c) = en(c) + nl%work(i) + dw
          end if
        end associate
      end do
      g(c, :) = nl%c2(1, mc)*psi(1:4) + nl%c2(2, mc)*(psi(5:8) + cshift(psi(5:8), 1))
      t(c, :) = nl%c2(3, mc)*psi(9:12)
    end do
  end subroutine nonlinear_law

  !> Whether a spring with n > 0 reversal points, last moving in direction dir from its
  !> committed strain e_c, reaches the trial strain e by going on along its current branch
  !> (the one from reversal point n) without passing that branch's aim: the previous reversal
  !> point, or for n = 1 the mirror of the first one (docs/nonlinear.md, section 4).
  pure logical function on_branch(n, dir, e, e_c, e_rev, er_pos, er_neg)
    integer(ip), intent(in) :: n, dir
    real(wp), intent(in) :: e, e_c, e_rev(:), er_pos, er_neg
    real(wp) :: aim
    integer :: d
    on_branch = .false.
    if (n <= 0 .or. dir == 0) return
    if (real(dir, wp)*(e - e_c) <= 0.0_wp) return
    if (n >= 2) then
      aim = e_rev(n - 1)
      d = merge(1, -1, aim > e_rev(n))
    else
      aim = masing_mirror_strain(e_rev(1), er_pos, er_neg)
      d = merge(-1, 1, e_rev(1) > 0.0_wp)
    end if
    on_branch = d == dir .and. real(d, wp)*(e - aim) < 0.0_wp
  end function on_branch

  !> The elastic cell law on a chunk: generalised stresses g = dPi/d eps (edges) and
  !> t = dPi/d s (corners) from edge strains ep and corner shear measures s.
  pure subroutine cell_law(k, m, ep, s, g, t)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    real(wp), intent(in) :: ep(chunk, 4), s(chunk, 4)
    real(wp), intent(out) :: g(chunk, 4), t(chunk, 4)
    real(wp) :: ce2, ch2, cg2, mx, my, sx, sy, dx, dy, gm
    integer :: c
    if (k%law == law_bending) then
      ! Pi = 2ce(mx^2+my^2) + 4ch(mx+my)^2 + 4cg gm^2 + cb(dx^2+dy^2): mean strains mx, my, mean
      ! shear gm (signs that make a uniform shear equal at every corner), bending measures
      ! dx = eps_top - eps_bottom, dy = eps_right - eps_left
      do c = 1, m
        mx = 0.5_wp*(ep(c, 1) + ep(c, 3))
        my = 0.5_wp*(ep(c, 2) + ep(c, 4))
        dx = ep(c, 3) - ep(c, 1)
        dy = ep(c, 2) - ep(c, 4)
        gm = 0.25_wp*(s(c, 1) - s(c, 2) + s(c, 3) - s(c, 4))
        sx = 2.0_wp*k%ce*mx + 4.0_wp*k%ch*(mx + my)
        sy = 2.0_wp*k%ce*my + 4.0_wp*k%ch*(mx + my)
        g(c, :) = [sx - 2.0_wp*k%cb*dx, sy + 2.0_wp*k%cb*dy, sx + 2.0_wp*k%cb*dx, &
                   sy - 2.0_wp*k%cb*dy]
        t(c, :) = 2.0_wp*k%cg*gm*[1.0_wp, -1.0_wp, 1.0_wp, -1.0_wp]
      end do
    else
      ce2 = 2.0_wp*k%ce
      ch2 = 2.0_wp*k%ch
      cg2 = 2.0_wp*k%cg
      do c = 1, m
        g(c, :) = [ce2*ep(c, 1) + ch2*(2.0_wp*ep(c, 1) + ep(c, 4) + ep(c, 2)), &
                   ce2*ep(c, 2) + ch2*(2.0_wp*ep(c, 2) + ep(c, 1) + ep(c, 3)), &
                   ce2*ep(c, 3) + ch2*(2.0_wp*ep(c, 3) + ep(c, 2) + ep(c, 4)), &
                   ce2*ep(c, 4) + ch2*(2.0_wp*ep(c, 4) + ep(c, 3) + ep(c, 1))]
        t(c, :) = cg2*s(c, :)
      end do
    end if
  end subroutine cell_law

  !> The elastic cell law on a chunk of cells of several materials: cell c follows the
  !> constants ks(mat(c)) (the same arithmetic as cell_law, cell by cell).
  pure subroutine cell_law_mixed(ks, mat, m, ep, s, g, t)
    type(cell_constants_t), intent(in) :: ks(:)
    integer, intent(in) :: mat(:), m
    real(wp), intent(in) :: ep(chunk, 4), s(chunk, 4)
    real(wp), intent(out) :: g(chunk, 4), t(chunk, 4)
    real(wp) :: e1(chunk, 4), s1(chunk, 4), g1(chunk, 4), t1(chunk, 4)
    integer :: c
    e1 = 0.0_wp
    s1 = 0.0_wp
    do c = 1, m
      e1(1, :) = ep(c, :)
      s1(1, :) = s(c, :)
      call cell_law(ks(mat(c)), 1, e1, s1, g1, t1)
      g(c, :) = g1(1, :)
      t(c, :) = t1(1, :)
    end do
  end subroutine cell_law_mixed
end module iem_cell_laws
