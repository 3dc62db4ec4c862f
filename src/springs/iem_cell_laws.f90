!> The cell laws of the force kernel, on a chunk of cells: the elastic law of the paper's
!> cell and of the bending-corrected cell (generalised stresses from edge strains and corner
!> shear measures, iem_spring_constants), the same cell by cell for several materials, and
!> the nonlinear (Masing) law of the paper's springs with its vectorisable fast path.
module iem_cell_laws
  use iem_kinds, only: wp, ip
  use iem_spring_constants, only: cell_constants_t, law_bending
  use iem_nonlinear_springs, only: nonlinear_springs_t, springs_per_cell, spring_kind
  use iem_masing, only: masing_springs, masing_constants, n_masing_constants
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
  !> cell's springs up to this state (trapezoidal increments from the committed state). The
  !> chunk's springs go through iem_masing's masing_springs together (a branch-free loop for
  !> the springs that stay on their curve, the state machine for the others).
  pure subroutine nonlinear_law(nl, c_first, m, ep, s, accept, g, t, en, mat)
    type(nonlinear_springs_t), intent(inout) :: nl
    integer, intent(in) :: c_first, m
    real(wp), intent(in) :: ep(chunk, 4), s(chunk, 4)
    logical, intent(in) :: accept
    real(wp), intent(out) :: g(chunk, 4), t(chunk, 4), en(chunk)
    !> Material of each cell of the chunk (absent: material 1).
    integer, intent(in), optional :: mat(:)
    integer, parameter :: ns_max = springs_per_cell*chunk
    ! per spring of the chunk (spring j of cell c at 12 (c - 1) + j, as in nl%state): its
    ! strain, its stress, the committed strain and stress before this call, the law's
    ! constants, half the energy coefficient, and the work increment
    real(wp) :: e(ns_max), psi(ns_max), e_old(ns_max), psi_old(ns_max)
    real(wp) :: p(ns_max, n_masing_constants), hc(ns_max), dw(ns_max)
    real(wp) :: q(springs_per_cell, n_masing_constants + 1)
    integer :: c, j, k, i0, ns, mc, mq, kind
    mc = 1
    mq = 0
    i0 = springs_per_cell*(c_first - 1)
    ns = springs_per_cell*m
    do c = 1, m
      if (present(mat)) mc = mat(c)
      if (mc /= mq) then
        ! the constants of each spring of a cell of material mc
        do j = 1, springs_per_cell
          kind = spring_kind(j)
          q(j, 1:n_masing_constants) = masing_constants(nl%er_pos(kind, mc), &
                                                        nl%er_neg(kind, mc))
          q(j, n_masing_constants + 1) = 0.5_wp*nl%c2(kind, mc)
        end do
        mq = mc
      end if
      ! the cell's spring strains (iem_nonlinear_springs' spring_strains)
      k = springs_per_cell*(c - 1)
      e(k + 1) = ep(c, 1)
      e(k + 2) = ep(c, 2)
      e(k + 3) = ep(c, 3)
      e(k + 4) = ep(c, 4)
      e(k + 5) = ep(c, 1) + ep(c, 4)
      e(k + 6) = ep(c, 2) + ep(c, 1)
      e(k + 7) = ep(c, 3) + ep(c, 2)
      e(k + 8) = ep(c, 4) + ep(c, 3)
      e(k + 9) = s(c, 1)
      e(k + 10) = s(c, 2)
      e(k + 11) = s(c, 3)
      e(k + 12) = s(c, 4)
      p(k + 1:k + springs_per_cell, :) = q(:, 1:n_masing_constants)
      hc(k + 1:k + springs_per_cell) = q(:, n_masing_constants + 1)
    end do
    associate(st => nl%state)
      call masing_springs(ns, int(st%depth), e, p, accept, st%strain(i0 + 1:i0 + ns), &
                          st%stress(i0 + 1:i0 + ns), st%dir(i0 + 1:i0 + ns), &
                          st%count(i0 + 1:i0 + ns), st%e_rev(:, i0 + 1:i0 + ns), &
                          st%s_rev(:, i0 + 1:i0 + ns), st%e_max_pos(i0 + 1:i0 + ns), &
                          st%e_max_neg(i0 + 1:i0 + ns), psi, e_old, psi_old)
    end associate
    do k = 1, ns
      dw(k) = hc(k)*(psi_old(k) + psi(k))*(e(k) - e_old(k))
    end do
    if (accept) then
      do k = 1, ns
        nl%work(i0 + k) = nl%work(i0 + k) + dw(k)
      end do
    end if
    ! the work of each cell, summed in the order of its springs (with accept, the work moved
    ! to this state), for the cells side by side
    en(1:m) = 0.0_wp
    if (accept) then
      do j = 1, springs_per_cell
        do c = 1, m
          en(c) = en(c) + nl%work(i0 + springs_per_cell*(c - 1) + j)
        end do
      end do
    else
      do j = 1, springs_per_cell
        do c = 1, m
          k = springs_per_cell*(c - 1) + j
          en(c) = en(c) + nl%work(i0 + k) + dw(k)
        end do
      end do
    end if
    mc = 1
    do c = 1, m
      if (present(mat)) mc = mat(c)
      k = springs_per_cell*(c - 1)
      ! g_q = 2 ce psi_q + 2 ch (psi_Poisson(q) + psi_Poisson(q + 1))
      g(c, 1) = nl%c2(1, mc)*psi(k + 1) + nl%c2(2, mc)*(psi(k + 5) + psi(k + 6))
      g(c, 2) = nl%c2(1, mc)*psi(k + 2) + nl%c2(2, mc)*(psi(k + 6) + psi(k + 7))
      g(c, 3) = nl%c2(1, mc)*psi(k + 3) + nl%c2(2, mc)*(psi(k + 7) + psi(k + 8))
      g(c, 4) = nl%c2(1, mc)*psi(k + 4) + nl%c2(2, mc)*(psi(k + 8) + psi(k + 5))
      t(c, 1) = nl%c2(3, mc)*psi(k + 9)
      t(c, 2) = nl%c2(3, mc)*psi(k + 10)
      t(c, 3) = nl%c2(3, mc)*psi(k + 11)
      t(c, 4) = nl%c2(3, mc)*psi(k + 12)
    end do
  end subroutine nonlinear_law

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
