!> Force kernel of the IEM cell: edge, Poisson and shear springs measured on the current
!> geometry (edge lengths and corner angles), so any rigid motion gives zero force.
!>
!> Strain measures (docs/model.md): edge q, from corner q to corner q+1, has the engineering
!> strain eps_q = l_q/l0_q - 1; corner q (edges q and q-1) has the shear measure
!> s_q = sin(gamma_q) = cos(theta_q), gamma_q = pi/2 - theta_q, computed from the unit edge
!> vectors without any angle function. s = gamma - gamma^3/6 + ..., so the tangent is that of
!> the angle and the shear stress differs from the angle form by gamma^2/6 (2e-5 at 1% shear).
module iem_cell_kernel
  use iem_kinds, only: wp
  use iem_spring_constants, only: cell_constants_t
  implicit none
  private
  public :: cell_strains, cell_energy, cell_force, cell_forces

  !> Cells per chunk of the vectorised kernel: the chunk's work arrays stay in L1 cache.
  integer, parameter :: chunk = 64

contains

  !> Edge strains eps(4) and corner shear measures s(4) = sin(gamma) of one cell.
  pure subroutine cell_strains(k, u, eps, s)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4)
    real(wp), intent(out) :: eps(4), s(4)
    real(wp) :: e(2, 4), il(4)
    call edges(k, u, e, il, eps)
    s(1) = -(e(1, 1)*e(1, 4) + e(2, 1)*e(2, 4))
    s(2) = -(e(1, 2)*e(1, 1) + e(2, 2)*e(2, 1))
    s(3) = -(e(1, 3)*e(1, 2) + e(2, 3)*e(2, 2))
    s(4) = -(e(1, 4)*e(1, 3) + e(2, 4)*e(2, 3))
  end subroutine cell_strains

  !> Strain energy of one cell (J) for corner displacements u(2, 4).
  pure real(wp) function cell_energy(k, u) result(en)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4)
    real(wp) :: eps(4), s(4)
    call cell_strains(k, u, eps, s)
    en = k%ce*sum(eps**2) + k%cg*sum(s**2) + k%ch*((eps(1) + eps(4))**2 + &
         (eps(2) + eps(1))**2 + (eps(3) + eps(2))**2 + (eps(4) + eps(3))**2)
  end function cell_energy

  !> Internal force f(2, 4) = dPi/dx of one cell, plus the stiffness-proportional damping force
  !> beta*K*v when beta > 0; returns the strain energy and the damping power f_damp . v.
  pure subroutine cell_force(k, u, v, beta, f, energy, damp_power)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4), v(2, 4), beta
    real(wp), intent(out) :: f(2, 4), energy, damp_power
    real(wp) :: e(2, 4), il(4), eps(4), s(4), sig(4), tau(4), ga(2, 4), gb(2, 4)
    real(wp) :: epsd(4), sd(4), dv(2, 4), sigd(4), taud(4)
    integer :: q, p, n

    call edges(k, u, e, il, eps)
    do q = 1, 4
      p = prev(q)
      ! corner q: a = d(q) (towards corner q+1), b = -d(p) (towards corner q-1)
      s(q) = -(e(1, q)*e(1, p) + e(2, q)*e(2, p))
      ga(:, q) = (-e(:, p) - s(q)*e(:, q))*il(q)       ! d s / d a
      gb(:, q) = (e(:, q) + s(q)*e(:, p))*il(p)        ! d s / d b
    end do
    do q = 1, 4
      sig(q) = 2.0_wp*(k%ce*eps(q) + k%ch*(2.0_wp*eps(q) + eps(prev(q)) + eps(next(q))))
      tau(q) = 2.0_wp*k%cg*s(q)
    end do
    energy = k%ce*sum(eps**2) + k%cg*sum(s**2) + k%ch*((eps(1) + eps(4))**2 + &
             (eps(2) + eps(1))**2 + (eps(3) + eps(2))**2 + (eps(4) + eps(3))**2)
    damp_power = 0.0_wp
    if (beta > 0.0_wp) then
      do q = 1, 4
        dv(:, q) = v(:, next(q)) - v(:, q)
      end do
      do q = 1, 4
        p = prev(q)
        epsd(q) = dot_product(e(:, q), dv(:, q))*k%il0(q)
        sd(q) = dot_product(ga(:, q), dv(:, q)) - dot_product(gb(:, q), dv(:, p))
      end do
      do q = 1, 4
        sigd(q) = 2.0_wp*beta*(k%ce*epsd(q) + k%ch*(2.0_wp*epsd(q) + epsd(prev(q)) + &
                  epsd(next(q))))
        taud(q) = 2.0_wp*beta*k%cg*sd(q)
      end do
      damp_power = sum(sigd*epsd) + sum(taud*sd)
      sig = sig + sigd
      tau = tau + taud
    end if
    f = 0.0_wp
    do q = 1, 4
      n = next(q)
      p = prev(q)
      ! edge q: d eps / d x(n) = e/l0, d eps / d x(q) = -e/l0
      f(:, n) = f(:, n) + sig(q)*k%il0(q)*e(:, q) + tau(q)*ga(:, q)
      f(:, q) = f(:, q) - sig(q)*k%il0(q)*e(:, q) - tau(q)*(ga(:, q) + gb(:, q))
      ! corner q: d s / d x(p) = gb
      f(:, p) = f(:, p) + tau(q)*gb(:, q)
    end do
  end subroutine cell_force

  !> Forces of many cells: corner forces fc(2, 4*(c-1)+q) of cell c, cell energies ec and
  !> damping powers pc, for the state y(4, :) = (u, v) of the nodes listed in cell_nodes.
  !> Same arithmetic as cell_force, arranged for speed: cells go in chunks whose corner values
  !> are first gathered into small unit-stride arrays, so the compiler vectorises the kernel
  !> across the cells of a chunk.
  pure subroutine cell_forces(k, cell_nodes, y, beta, fc, ec, pc)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: cell_nodes(:, :)
    real(wp), intent(in) :: y(:, :), beta
    real(wp), intent(out) :: fc(:, :), ec(:), pc(:)
    real(wp) :: ux(chunk, 4), uy(chunk, 4), vx(chunk, 4), vy(chunk, 4)
    real(wp) :: fx(chunk, 4), fy(chunk, 4), en(chunk), pw(chunk)
    integer :: c0, m, c, q, nc
    logical :: damped

    nc = size(cell_nodes, 2)
    damped = beta > 0.0_wp
    vx = 0.0_wp
    vy = 0.0_wp
    do c0 = 1, nc, chunk
      m = min(chunk, nc - c0 + 1)
      do q = 1, 4
        do c = 1, m
          ux(c, q) = y(1, cell_nodes(q, c0 + c - 1))
          uy(c, q) = y(2, cell_nodes(q, c0 + c - 1))
        end do
      end do
      if (damped) then
        do q = 1, 4
          do c = 1, m
            vx(c, q) = y(3, cell_nodes(q, c0 + c - 1))
            vy(c, q) = y(4, cell_nodes(q, c0 + c - 1))
          end do
        end do
      end if
      call chunk_forces(k, m, damped, beta, ux, uy, vx, vy, fx, fy, en, pw)
      do c = 1, m
        do q = 1, 4
          fc(1, 4*(c0 + c - 2) + q) = fx(c, q)
          fc(2, 4*(c0 + c - 2) + q) = fy(c, q)
        end do
        ec(c0 + c - 1) = en(c)
        pc(c0 + c - 1) = pw(c)
      end do
    end do
  end subroutine cell_forces

  !> Kernel over one chunk of m cells with corner values in unit-stride arrays (cell index
  !> first): the single-cell arithmetic of cell_force in three branch-free loops (geometry and
  !> elastic stresses; damping, only when damped; corner forces) that the compiler vectorises.
  pure subroutine chunk_forces(k, m, damped, beta, ux, uy, vx, vy, fx, fy, en, pw)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    logical, intent(in) :: damped
    real(wp), intent(in) :: beta
    real(wp), intent(in) :: ux(chunk, 4), uy(chunk, 4), vx(chunk, 4), vy(chunk, 4)
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4), en(chunk), pw(chunk)
    ! per cell: unit edge vectors e, shear gradients a (d s/d a) and b (d s/d b), edge and
    ! corner generalised stresses g and t
    real(wp) :: ex(chunk, 4), ey(chunk, 4), ax(chunk, 4), ay(chunk, 4)
    real(wp) :: bx(chunk, 4), by(chunk, 4), g(chunk, 4), t(chunk, 4)
    real(wp) :: e1x, e1y, e2x, e2y, e3x, e3y, e4x, e4y, l1, l2, l3, l4, i1, i2, i3, i4
    real(wp) :: ep1, ep2, ep3, ep4, s1, s2, s3, s4
    real(wp) :: w1x, w1y, w2x, w2y, w3x, w3y, w4x, w4y, d1, d2, d3, d4, r1, r2, r3, r4
    real(wp) :: q1, q2, q3, q4, ce2, ch2, cg2, ilx, ily, bg
    integer :: c

    ce2 = 2.0_wp*k%ce
    ch2 = 2.0_wp*k%ch
    cg2 = 2.0_wp*k%cg
    ilx = k%il0(1)
    ily = k%il0(2)
    do c = 1, m
      ! edge vectors (current), lengths, unit vectors, strains
      e1x = k%lx + ux(c, 2) - ux(c, 1)
      e1y = uy(c, 2) - uy(c, 1)
      e2x = ux(c, 3) - ux(c, 2)
      e2y = k%ly + uy(c, 3) - uy(c, 2)
      e3x = -k%lx + ux(c, 4) - ux(c, 3)
      e3y = uy(c, 4) - uy(c, 3)
      e4x = ux(c, 1) - ux(c, 4)
      e4y = -k%ly + uy(c, 1) - uy(c, 4)
      l1 = sqrt(e1x**2 + e1y**2)
      l2 = sqrt(e2x**2 + e2y**2)
      l3 = sqrt(e3x**2 + e3y**2)
      l4 = sqrt(e4x**2 + e4y**2)
      i1 = 1.0_wp/l1
      i2 = 1.0_wp/l2
      i3 = 1.0_wp/l3
      i4 = 1.0_wp/l4
      ep1 = l1*ilx - 1.0_wp
      ep2 = l2*ily - 1.0_wp
      ep3 = l3*ilx - 1.0_wp
      ep4 = l4*ily - 1.0_wp
      e1x = e1x*i1
      e1y = e1y*i1
      e2x = e2x*i2
      e2y = e2y*i2
      e3x = e3x*i3
      e3y = e3y*i3
      e4x = e4x*i4
      e4y = e4y*i4
      ! shear measures s = sin(gamma) at corners 1..4 (corner q joins edges q and q-1)
      s1 = -(e1x*e4x + e1y*e4y)
      s2 = -(e2x*e1x + e2y*e1y)
      s3 = -(e3x*e2x + e3y*e2y)
      s4 = -(e4x*e3x + e4y*e3y)
      ex(c, :) = [e1x, e2x, e3x, e4x]
      ey(c, :) = [e1y, e2y, e3y, e4y]
      ! d s_q / d a (a: edge q) and d s_q / d b (b: reversed edge q-1)
      ax(c, :) = [(-e4x - s1*e1x)*i1, (-e1x - s2*e2x)*i2, (-e2x - s3*e3x)*i3, (-e3x - s4*e4x)*i4]
      ay(c, :) = [(-e4y - s1*e1y)*i1, (-e1y - s2*e2y)*i2, (-e2y - s3*e3y)*i3, (-e3y - s4*e4y)*i4]
      bx(c, :) = [(e1x + s1*e4x)*i4, (e2x + s2*e1x)*i1, (e3x + s3*e2x)*i2, (e4x + s4*e3x)*i3]
      by(c, :) = [(e1y + s1*e4y)*i4, (e2y + s2*e1y)*i1, (e3y + s3*e2y)*i2, (e4y + s4*e3y)*i3]
      ! generalised stresses of edges (with Poisson) and corners
      g(c, :) = [ce2*ep1 + ch2*(2.0_wp*ep1 + ep4 + ep2), ce2*ep2 + ch2*(2.0_wp*ep2 + ep1 + ep3), &
                 ce2*ep3 + ch2*(2.0_wp*ep3 + ep2 + ep4), ce2*ep4 + ch2*(2.0_wp*ep4 + ep3 + ep1)]
      t(c, :) = cg2*[s1, s2, s3, s4]
      en(c) = k%ce*(ep1**2 + ep2**2 + ep3**2 + ep4**2) + k%cg*(s1**2 + s2**2 + s3**2 + s4**2) &
              + k%ch*((ep1 + ep4)**2 + (ep2 + ep1)**2 + (ep3 + ep2)**2 + (ep4 + ep3)**2)
      pw(c) = 0.0_wp
    end do
    if (damped) then
      bg = beta*cg2
      do c = 1, m
        ! strain rates from the corner velocity differences along the edges
        w1x = vx(c, 2) - vx(c, 1)
        w1y = vy(c, 2) - vy(c, 1)
        w2x = vx(c, 3) - vx(c, 2)
        w2y = vy(c, 3) - vy(c, 2)
        w3x = vx(c, 4) - vx(c, 3)
        w3y = vy(c, 4) - vy(c, 3)
        w4x = vx(c, 1) - vx(c, 4)
        w4y = vy(c, 1) - vy(c, 4)
        d1 = (ex(c, 1)*w1x + ey(c, 1)*w1y)*ilx
        d2 = (ex(c, 2)*w2x + ey(c, 2)*w2y)*ily
        d3 = (ex(c, 3)*w3x + ey(c, 3)*w3y)*ilx
        d4 = (ex(c, 4)*w4x + ey(c, 4)*w4y)*ily
        r1 = ax(c, 1)*w1x + ay(c, 1)*w1y - bx(c, 1)*w4x - by(c, 1)*w4y
        r2 = ax(c, 2)*w2x + ay(c, 2)*w2y - bx(c, 2)*w1x - by(c, 2)*w1y
        r3 = ax(c, 3)*w3x + ay(c, 3)*w3y - bx(c, 3)*w2x - by(c, 3)*w2y
        r4 = ax(c, 4)*w4x + ay(c, 4)*w4y - bx(c, 4)*w3x - by(c, 4)*w3y
        q1 = beta*(ce2*d1 + ch2*(2.0_wp*d1 + d4 + d2))
        q2 = beta*(ce2*d2 + ch2*(2.0_wp*d2 + d1 + d3))
        q3 = beta*(ce2*d3 + ch2*(2.0_wp*d3 + d2 + d4))
        q4 = beta*(ce2*d4 + ch2*(2.0_wp*d4 + d3 + d1))
        pw(c) = q1*d1 + q2*d2 + q3*d3 + q4*d4 + bg*(r1**2 + r2**2 + r3**2 + r4**2)
        g(c, :) = g(c, :) + [q1, q2, q3, q4]
        t(c, :) = t(c, :) + bg*[r1, r2, r3, r4]
      end do
    end if
    do c = 1, m
      ! edge forces per unit reference length along the unit vectors: corner q+1 gets
      ! +g_q e_q + t_q a_q, corner q gets -g_q e_q - t_q (a_q + b_q), corner q-1 gets t_q b_q
      g(c, :) = g(c, :)*[ilx, ily, ilx, ily]
      fx(c, 1) = -g(c, 1)*ex(c, 1) - t(c, 1)*(ax(c, 1) + bx(c, 1)) + g(c, 4)*ex(c, 4) &
                 + t(c, 4)*ax(c, 4) + t(c, 2)*bx(c, 2)
      fy(c, 1) = -g(c, 1)*ey(c, 1) - t(c, 1)*(ay(c, 1) + by(c, 1)) + g(c, 4)*ey(c, 4) &
                 + t(c, 4)*ay(c, 4) + t(c, 2)*by(c, 2)
      fx(c, 2) = -g(c, 2)*ex(c, 2) - t(c, 2)*(ax(c, 2) + bx(c, 2)) + g(c, 1)*ex(c, 1) &
                 + t(c, 1)*ax(c, 1) + t(c, 3)*bx(c, 3)
      fy(c, 2) = -g(c, 2)*ey(c, 2) - t(c, 2)*(ay(c, 2) + by(c, 2)) + g(c, 1)*ey(c, 1) &
                 + t(c, 1)*ay(c, 1) + t(c, 3)*by(c, 3)
      fx(c, 3) = -g(c, 3)*ex(c, 3) - t(c, 3)*(ax(c, 3) + bx(c, 3)) + g(c, 2)*ex(c, 2) &
                 + t(c, 2)*ax(c, 2) + t(c, 4)*bx(c, 4)
      fy(c, 3) = -g(c, 3)*ey(c, 3) - t(c, 3)*(ay(c, 3) + by(c, 3)) + g(c, 2)*ey(c, 2) &
                 + t(c, 2)*ay(c, 2) + t(c, 4)*by(c, 4)
      fx(c, 4) = -g(c, 4)*ex(c, 4) - t(c, 4)*(ax(c, 4) + bx(c, 4)) + g(c, 3)*ex(c, 3) &
                 + t(c, 3)*ax(c, 3) + t(c, 1)*bx(c, 1)
      fy(c, 4) = -g(c, 4)*ey(c, 4) - t(c, 4)*(ay(c, 4) + by(c, 4)) + g(c, 3)*ey(c, 3) &
                 + t(c, 3)*ay(c, 3) + t(c, 1)*by(c, 1)
    end do
  end subroutine chunk_forces

  !> Unit edge vectors e(:, q), inverse current lengths il(q) and strains eps(q).
  pure subroutine edges(k, u, e, il, eps)
    type(cell_constants_t), intent(in) :: k
    real(wp), intent(in) :: u(2, 4)
    real(wp), intent(out) :: e(2, 4), il(4), eps(4)
    real(wp) :: l
    integer :: q
    e(:, 1) = [k%lx + u(1, 2) - u(1, 1), u(2, 2) - u(2, 1)]
    e(:, 2) = [u(1, 3) - u(1, 2), k%ly + u(2, 3) - u(2, 2)]
    e(:, 3) = [-k%lx + u(1, 4) - u(1, 3), u(2, 4) - u(2, 3)]
    e(:, 4) = [u(1, 1) - u(1, 4), -k%ly + u(2, 1) - u(2, 4)]
    do q = 1, 4
      l = sqrt(e(1, q)**2 + e(2, q)**2)
      il(q) = 1.0_wp/l
      eps(q) = l*k%il0(q) - 1.0_wp
      e(:, q) = e(:, q)*il(q)
    end do
  end subroutine edges

  pure integer function next(q)
    integer, intent(in) :: q
    next = mod(q, 4) + 1
  end function next

  pure integer function prev(q)
    integer, intent(in) :: q
    prev = mod(q + 2, 4) + 1
  end function prev
end module iem_cell_kernel
