!> Force kernel of one IEM cell: edge, Poisson and shear springs measured on the current
!> geometry (edge lengths and corner angles), so any rigid motion gives zero force.
module iem_cell_kernel
  use iem_kinds, only: wp
  use iem_spring_constants, only: cell_constants_t
  implicit none
  private
  public :: cell_strains, cell_energy, cell_force

contains

  !> Edge strains eps(4) and corner shear angles gamma(4) of a cell from corner displacements.
  !> Edge q runs from corner q to corner q+1; corner q joins edges q and q-1.
  pure subroutine cell_strains(k, u, eps, gam)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4)
    real(wp), intent(out) :: eps(4), gam(4)
    real(wp) :: d(2, 4), l0(4)
    integer :: q
    call edge_vectors(k, u, d, l0)
    do q = 1, 4
      eps(q) = edge_strain(d(:, q), l0(q))
    end do
    do q = 1, 4
      gam(q) = corner_shear(d(:, q), d(:, prev(q)))
    end do
  end subroutine cell_strains

  !> Strain energy of a cell (J) for corner displacements u(2, 4).
  pure real(wp) function cell_energy(k, u) result(e)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4)
    real(wp) :: eps(4), gam(4)
    integer :: q
    call cell_strains(k, u, eps, gam)
    e = 0.0_wp
    do q = 1, 4
      e = e + k%ce*eps(q)**2 + k%ch*(eps(q) + eps(prev(q)))**2 + k%cg*gam(q)**2
    end do
  end function cell_energy

  !> Internal force f(2, 4) = dPi/dx of a cell, plus the stiffness-proportional damping force
  !> beta*K*v when beta > 0; returns the strain energy and the damping power f_damp . v.
  pure subroutine cell_force(k, u, v, beta, f, energy, damp_power)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4), v(2, 4), beta
    real(wp), intent(out) :: f(2, 4), energy, damp_power
    real(wp) :: d(2, 4), l0(4), e(2, 4), eps(4), gam(4), sig(4), tau(4)
    real(wp) :: ga(2, 4), gb(2, 4), epsd(4), gamd(4), sigd(4), taud(4), len2a, len2b, l
    integer :: q, p, n

    call edge_vectors(k, u, d, l0)
    do q = 1, 4
      l = norm2(d(:, q))
      e(:, q) = d(:, q)/l
      eps(q) = edge_strain(d(:, q), l0(q))
    end do
    do q = 1, 4
      p = prev(q)
      ! corner q: a = d(q) towards corner q+1, b = -d(p) towards corner q-1
      gam(q) = corner_shear(d(:, q), d(:, p))
      len2a = d(1, q)**2 + d(2, q)**2
      len2b = d(1, p)**2 + d(2, p)**2
      ga(:, q) = [-d(2, q), d(1, q)]/len2a        ! d gamma / d a
      gb(:, q) = [-d(2, p), d(1, p)]/len2b        ! d gamma / d b, b = -d(p)
    end do
    energy = 0.0_wp
    do q = 1, 4
      n = next(q)
      p = prev(q)
      sig(q) = 2.0_wp*(k%ce*eps(q) + k%ch*(eps(q) + eps(p)) + k%ch*(eps(n) + eps(q)))
      tau(q) = 2.0_wp*k%cg*gam(q)
      energy = energy + k%ce*eps(q)**2 + k%ch*(eps(q) + eps(p))**2 + k%cg*gam(q)**2
    end do
    damp_power = 0.0_wp
    if (beta > 0.0_wp) then
      do q = 1, 4
        n = next(q)
        p = prev(q)
        epsd(q) = dot_product(e(:, q), v(:, n) - v(:, q))/l0(q)
        gamd(q) = dot_product(ga(:, q), v(:, n) - v(:, q)) + &
                  dot_product(gb(:, q), v(:, p) - v(:, q))
      end do
      do q = 1, 4
        n = next(q)
        p = prev(q)
        sigd(q) = 2.0_wp*beta*(k%ce*epsd(q) + k%ch*(epsd(q) + epsd(p)) + &
                               k%ch*(epsd(n) + epsd(q)))
        taud(q) = 2.0_wp*beta*k%cg*gamd(q)
        damp_power = damp_power + sigd(q)*epsd(q) + taud(q)*gamd(q)
      end do
      sig = sig + sigd
      tau = tau + taud
    end if
    f = 0.0_wp
    do q = 1, 4
      n = next(q)
      p = prev(q)
      ! edge q: d eps / d x(n) = e/l0, d eps / d x(q) = -e/l0
      f(:, n) = f(:, n) + sig(q)/l0(q)*e(:, q)
      f(:, q) = f(:, q) - sig(q)/l0(q)*e(:, q)
      ! corner q: d gamma / d x(n) = ga, d gamma / d x(p) = gb, d gamma / d x(q) = -(ga+gb)
      f(:, n) = f(:, n) + tau(q)*ga(:, q)
      f(:, p) = f(:, p) + tau(q)*gb(:, q)
      f(:, q) = f(:, q) - tau(q)*(ga(:, q) + gb(:, q))
    end do
  end subroutine cell_force

  !> Current edge vectors d(:, q) = x(q+1) - x(q) and reference lengths l0(q).
  pure subroutine edge_vectors(k, u, d, l0)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4)
    real(wp), intent(out) :: d(2, 4), l0(4)
    d(:, 1) = [k%lx, 0.0_wp] + u(:, 2) - u(:, 1)
    d(:, 2) = [0.0_wp, k%ly] + u(:, 3) - u(:, 2)
    d(:, 3) = [-k%lx, 0.0_wp] + u(:, 4) - u(:, 3)
    d(:, 4) = [0.0_wp, -k%ly] + u(:, 1) - u(:, 4)
    l0 = [k%lx, k%ly, k%lx, k%ly]
  end subroutine edge_vectors

  !> Axial (engineering) strain (l - l0)/l0 of an edge with current vector d.
  pure real(wp) function edge_strain(d, l0) result(eps)
    real(wp), intent(in) :: d(2), l0
    real(wp) :: l
    l = norm2(d)
    eps = (l - l0)/l0
  end function edge_strain

  !> Shear angle pi/2 - theta at a corner whose outgoing edge is a and incoming edge is dp
  !> (so the second edge from the corner is b = -dp); exact for any rotation.
  pure real(wp) function corner_shear(a, dp) result(gam)
    real(wp), intent(in) :: a(2), dp(2)
    real(wp) :: cr, dt
    ! theta = atan2(a x b, a . b) with b = -dp; gamma = pi/2 - theta = atan2(a . b, a x b)
    cr = -(a(1)*dp(2) - a(2)*dp(1))
    dt = -(a(1)*dp(1) + a(2)*dp(2))
    gam = atan2(dt, cr)
  end function corner_shear

  pure integer function next(q)
    integer, intent(in) :: q
    next = mod(q, 4) + 1
  end function next

  pure integer function prev(q)
    integer, intent(in) :: q
    prev = mod(q + 2, 4) + 1
  end function prev
end module iem_cell_kernel
