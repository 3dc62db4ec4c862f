!> Stable time step of RK4 for the lattice: omega_max from the cell-level (element-by-element)
!> bound, and the largest step for which every damped mode stays in RK4's stability region.
module iem_stable_dt
  use iem_kinds, only: wp
  use iem_constants, only: rk4_imag_limit
  use iem_spring_constants, only: cell_constants_t
  use iem_cell_kernel, only: cell_force
  implicit none
  private
  public :: cell_stiffness, cell_omega_max, rk4_stable_dt, rk4_amplification, jacobi_eigenvalues

contains

  !> Tangent stiffness K(8, 8) of a cell at rest, by central differences of the force kernel.
  pure function cell_stiffness(k) result(kmat)
    type(cell_constants_t), intent(in) :: k
    real(wp) :: kmat(8, 8)
    real(wp) :: u(2, 4), v(2, 4), fp(2, 4), fm(2, 4), e, p, h
    integer :: col
    h = 1.0e-6_wp*min(k%lx, k%ly)
    v = 0.0_wp
    do col = 1, 8
      u = 0.0_wp
      u(mod(col - 1, 2) + 1, (col - 1)/2 + 1) = h
      call cell_force(k, u, v, 0.0_wp, fp, e, p)
      u = -u
      call cell_force(k, u, v, 0.0_wp, fm, e, p)
      kmat(:, col) = reshape(fp - fm, [8])/(2.0_wp*h)
    end do
    kmat = 0.5_wp*(kmat + transpose(kmat))
  end function cell_stiffness

  !> Highest natural frequency (rad/s) of one cell with its lumped corner mass m_corner: an
  !> upper bound of the lattice's omega_max (element-by-element bound).
  pure real(wp) function cell_omega_max(k, m_corner) result(w)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: m_corner
    real(wp) :: ev(8)
    ev = jacobi_eigenvalues(cell_stiffness(k)/m_corner)
    w = sqrt(max(maxval(ev), 0.0_wp))
  end function cell_omega_max

  !> Largest dt for which RK4 is stable for every mode omega in [0, omega_max] under Rayleigh
  !> damping c(omega) = alpha + beta*omega^2 (2*sqrt(2)/omega_max when undamped).
  pure real(wp) function rk4_stable_dt(omega_max, alpha, beta) result(dt)
    real(wp), intent(in) :: omega_max, alpha, beta
    integer, parameter :: n_samples = 400
    integer :: s
    real(wp) :: w, c, dtw
    complex(wp) :: lam(2), disc
    if (alpha == 0.0_wp .and. beta == 0.0_wp) then
      dt = rk4_imag_limit/omega_max
      return
    end if
    dt = huge(1.0_wp)
    do s = 0, n_samples
      w = omega_max*real(s, wp)/n_samples
      c = alpha + beta*w**2
      disc = sqrt(cmplx(c**2 - 4.0_wp*w**2, 0.0_wp, wp))
      lam(1) = 0.5_wp*(-c + disc)
      lam(2) = 0.5_wp*(-c - disc)
      dtw = min(ray_limit(lam(1)), ray_limit(lam(2)))
      dt = min(dt, dtw)
    end do
  end function rk4_stable_dt

  !> RK4 amplification factor R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24.
  pure complex(wp) function rk4_amplification(z) result(r)
    complex(wp), intent(in) :: z
    r = 1.0_wp + z*(1.0_wp + z*(0.5_wp + z*(1.0_wp/6.0_wp + z/24.0_wp)))
  end function rk4_amplification

  !> Largest h with |R(h*lam)| <= 1 on [0, h] (huge for lam = 0).
  pure real(wp) function ray_limit(lam) result(h)
    complex(wp), intent(in) :: lam
    real(wp) :: r, lo, hi, step
    integer :: it
    if (abs(lam) == 0.0_wp) then
      h = huge(1.0_wp)
      return
    end if
    step = 1.0e-3_wp
    r = 0.0_wp
    do while (r < 4.0_wp)
      if (abs(rk4_amplification((r + step)*lam/abs(lam))) > 1.0_wp + 1.0e-13_wp) exit
      r = r + step
    end do
    lo = r
    hi = r + step
    do it = 1, 60
      r = 0.5_wp*(lo + hi)
      if (abs(rk4_amplification(r*lam/abs(lam))) > 1.0_wp + 1.0e-13_wp) then
        hi = r
      else
        lo = r
      end if
    end do
    h = lo/abs(lam)
  end function ray_limit

  !> Eigenvalues of a small symmetric matrix by cyclic Jacobi rotations.
  pure function jacobi_eigenvalues(a_in) result(ev)
    real(wp), intent(in) :: a_in(:, :)
    real(wp) :: ev(size(a_in, 1))
    real(wp) :: a(size(a_in, 1), size(a_in, 1)), off, theta, t, c, s, tau, apq, scale
    real(wp) :: akp, akq
    integer :: n, p, q, k, sweep
    a = a_in
    n = size(a, 1)
    scale = max(maxval(abs(a)), tiny(1.0_wp))
    do sweep = 1, 100
      off = 0.0_wp
      do p = 1, n - 1
        do q = p + 1, n
          off = off + a(p, q)**2
        end do
      end do
      if (sqrt(off) <= 1.0e-15_wp*scale) exit
      do p = 1, n - 1
        do q = p + 1, n
          apq = a(p, q)
          if (abs(apq) <= 1.0e-300_wp) cycle
          theta = (a(q, q) - a(p, p))/(2.0_wp*apq)
          t = sign(1.0_wp, theta)/(abs(theta) + sqrt(theta**2 + 1.0_wp))
          c = 1.0_wp/sqrt(t**2 + 1.0_wp)
          s = t*c
          tau = s/(1.0_wp + c)
          a(p, p) = a(p, p) - t*apq
          a(q, q) = a(q, q) + t*apq
          a(p, q) = 0.0_wp
          a(q, p) = 0.0_wp
          do k = 1, n
            if (k == p .or. k == q) cycle
            akp = a(k, p)
            akq = a(k, q)
            a(k, p) = akp - s*(akq + tau*akp)
            a(p, k) = a(k, p)
            a(k, q) = akq + s*(akp - tau*akq)
            a(q, k) = a(k, q)
          end do
        end do
      end do
    end do
    do k = 1, n
      ev(k) = a(k, k)
    end do
  end function jacobi_eigenvalues
end module iem_stable_dt
